"""Fixtures of the reliability and security tests: a throwaway PKI made with ``openssl`` and the
shipped secure Zenoh configs (``docker/zenoh/*-secure.json5``) pointed at it, on loopback only."""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
import zenoh

from ..conftest import SOFIA

REPO = Path(__file__).resolve().parents[2]
USERS = ("calibrator", "detector", "gripper", "camera", "replay", "arm", "operator", "sofia", "viz", "ros2")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _openssl(*args: str, cwd: Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True, timeout=60)


def make_ca(directory: Path, name: str) -> None:
    """``<name>.pem`` and ``<name>.key``: a self-signed CA valid for two days."""
    _openssl("req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
             "-keyout", f"{name}.key", "-out", f"{name}.pem", "-days", "2", "-subj", f"/CN={name}",
             "-addext", "basicConstraints=critical,CA:TRUE",
             "-addext", "keyUsage=critical,keyCertSign,cRLSign", cwd=directory)  # fmt: skip


def make_cert(directory: Path, ca: str, name: str) -> Path:
    """``<name>/cert.pem`` and ``<name>/key.pem`` signed by CA ``ca``, naming localhost and 127.0.0.1."""
    out = directory / name
    out.mkdir()
    (out / "ext.cnf").write_text(
        "subjectAltName=DNS:localhost,IP:127.0.0.1\nbasicConstraints=CA:FALSE\n"
        "keyUsage=critical,digitalSignature\nextendedKeyUsage=serverAuth,clientAuth\n"
    )
    _openssl("req", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
             "-keyout", f"{name}/key.pem", "-out", f"{name}/csr.pem", "-subj", f"/CN={name}", cwd=directory)  # fmt: skip
    _openssl("x509", "-req", "-in", f"{name}/csr.pem", "-CA", f"{ca}.pem", "-CAkey", f"{ca}.key",
             "-CAcreateserial", "-out", f"{name}/cert.pem", "-days", "2", "-extfile", f"{name}/ext.cnf",
             cwd=directory)  # fmt: skip
    return out


@dataclass
class Pki:
    """Where the throwaway certificates are: the layout of ./certs that compose.secure.yaml mounts."""

    dir: Path
    passwords: dict[str, str]

    def password_file(self, user: str) -> Path:
        path = self.dir / f"{user}.password"
        path.write_text(self.passwords[user] + "\n")
        return path


@pytest.fixture(scope="session")
def pki(tmp_path_factory: pytest.TempPathFactory) -> Pki:
    if shutil.which("openssl") is None:
        pytest.fail("openssl is needed to make the test certificates")
    d = tmp_path_factory.mktemp("certs")
    make_ca(d, "minica")  # the names of docker/compose.secure.yaml's ./certs
    make_cert(d, "minica", "robot-pc")
    make_cert(d, "minica", "sofia-client")
    make_ca(d, "other-ca")
    make_cert(d, "other-ca", "other-client")
    passwords = {u: f"{u}-pw-{i}7x" for i, u in enumerate(USERS)}
    (d / "credentials.txt").write_text("".join(f"{u}:{p}\n" for u, p in passwords.items()))
    return Pki(d, passwords)


def render(src: Path, dest: Path, replacements: dict[str, str]) -> Path:
    """A copy of the json5 config ``src`` with strings replaced (paths and endpoints)."""
    text = src.read_text()
    for old, new in replacements.items():
        assert old in text, f"{old!r} not in {src}"
        text = text.replace(old, new)
    dest.write_text(text)
    return dest


@dataclass
class SecureRouter:
    endpoint: str  # tls/localhost:<port>
    port: int
    client_file: Path  # client-secure.json5 pointed at this router and the test's certificates

    def client_config(self, user: str | None = "sofia", password: str | None = None,
                      **tls: str | None) -> zenoh.Config:  # fmt: skip
        """The shipped client config; ``user=None`` drops user/password, a TLS key set to None
        drops that setting (e.g. ``connect_certificate=None``)."""
        conf = zenoh.Config.from_file(str(self.client_file))
        if user is None:
            conf.insert_json5("transport/auth/usrpwd", "{}")
        else:
            conf.insert_json5("transport/auth/usrpwd/user", json.dumps(user))
            conf.insert_json5("transport/auth/usrpwd/password", json.dumps(password))
        for key, value in tls.items():
            conf.insert_json5(f"transport/link/tls/{key}", json.dumps(value))
        return conf


@pytest.fixture(scope="module")
def secure_router(pki: Pki, tmp_path_factory: pytest.TempPathFactory) -> Iterator[SecureRouter]:
    """``sofia router`` running docker/zenoh/router-secure.json5 (TLS, mTLS, user/password, access
    control) on ``tls/127.0.0.1:<free port>`` with the throwaway certificates (one per module)."""
    tmp = tmp_path_factory.mktemp("secure-router")
    port = free_port()
    router_file = render(REPO / "docker/zenoh/router-secure.json5", tmp / "router.json5", {
        "/etc/zenoh/certs/": f"{pki.dir}/", "tls/[::]:7447": f"tls/127.0.0.1:{port}",
        'http_port: "127.0.0.1:8000"': 'http_port: "127.0.0.1:0"',
    })  # fmt: skip
    client_file = render(REPO / "docker/zenoh/client-secure.json5", tmp / "client.json5", {
        "/etc/sofia/certs/": f"{pki.dir}/", "tls/robot-pc:7447": f"tls/localhost:{port}",
    })  # fmt: skip
    log_path = tmp / "router.log"
    with open(log_path, "wb") as log:
        router = subprocess.Popen([SOFIA, "router", "--zenoh-config", str(router_file)],
                                  stdout=log, stderr=subprocess.STDOUT, cwd=REPO)  # fmt: skip
    try:
        deadline = time.monotonic() + 60
        while "router ready" not in log_path.read_text(errors="replace"):
            assert router.poll() is None and time.monotonic() < deadline, log_path.read_text()
            time.sleep(0.05)
        yield SecureRouter(f"tls/localhost:{port}", port, client_file)
    finally:
        router.terminate()
        router.wait(20)


class Service:
    """A ``sofia`` process (separate, as in production) with its log in a file."""

    def __init__(self, args: list[str], env: dict[str, str], log_path: Path) -> None:
        self.args, self.log_path = args, log_path
        with open(log_path, "wb") as log:
            self.popen = subprocess.Popen([SOFIA, *args], stdout=log, stderr=subprocess.STDOUT, env=env,
                                          cwd=REPO, start_new_session=True)  # fmt: skip

    @property
    def pid(self) -> int:
        return self.popen.pid

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")

    def wait_for_log(self, text: str, timeout: float = 60.0) -> None:
        deadline = time.monotonic() + timeout
        while text not in self.log():
            if self.popen.poll() is not None or time.monotonic() > deadline:
                raise AssertionError(f"{text!r} not in the log of sofia {' '.join(self.args)}:\n{self.log()}")
            time.sleep(0.05)

    def stop(self) -> None:
        if self.popen.poll() is None:
            self.popen.terminate()
            try:
                self.popen.wait(15)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait(5)


@pytest.fixture(scope="session")
def module_robot() -> str:
    """The robot id of the shared detector (one per test run)."""
    return "r" + uuid.uuid4().hex[:10]


@pytest.fixture(scope="session")
def detector(module_robot: str, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Service]:
    """``sofia detector serve`` with the default Zenoh settings, its detect queries capped at 4 MB."""
    env = dict(os.environ, SOFIA_ROBOT=module_robot, PYTHONUNBUFFERED="1",
               SOFIA_PAYLOAD_LIMITS=f"sofia/{module_robot}/detector/detect=4000000")  # fmt: skip
    service = Service(["detector", "serve"], env, tmp_path_factory.mktemp("detector") / "detector.log")
    try:
        service.wait_for_log("detector ready")
        yield service
    finally:
        service.stop()
