"""compose.yaml and the Dockerfiles, checked without a Docker engine.

The compose file is validated against the Compose Specification JSON Schema (vendored in
``data/``); each Dockerfile is parsed to learn which SofIA packages its image installs, and each
service's ``sofia`` command (and healthcheck) must then be served by those packages alone: by the
``sofia.commands`` entry points of their pyproject.toml, and by an argument parser built from
nothing but those entry points. The Zenoh router configs are loaded by the real Zenoh library.
"""

from __future__ import annotations

import copy
import fnmatch
import functools
import json
import os
import posixpath
import re
import shlex
import socket
import subprocess
import sys
import time
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib.metadata import PackageNotFoundError, distribution, packages_distributions
from pathlib import Path
from subprocess import PIPE
from typing import Any

import jsonschema
import numpy as np
import pytest
import yaml
import zenoh
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from sofia_runtime.zenoh_config import resolve, zenoh_config
from sofia_schemas.keys import Keys

from ..conftest import SOFIA

REPO = Path(__file__).resolve().parents[2]
SCHEMA = Path(__file__).with_name("data") / "compose-spec.json"
ROUTER = "zenoh"
RESTART_POLICIES = {"unless-stopped", "on-failure", "always"}
_VAR = re.compile(r"\$\{(\w+)(?::?-([^}]*))?\}")


@functools.cache
def compose() -> dict[str, Any]:
    return yaml.safe_load((REPO / "compose.yaml").read_text())


def services() -> dict[str, dict[str, Any]]:
    return compose()["services"]


SOFIA_SERVICES = [name for name in services() if name != ROUTER]
BUILT_SERVICES = [name for name, s in services().items() if "build" in s]


def interpolate(text: str) -> str:
    """Compose-style ``${VAR:-default}`` with the defaults (the tests ignore the caller's shell)."""

    def sub(m: re.Match[str]) -> str:
        assert m.group(2) is not None, f"${{{m.group(1)}}} in compose.yaml has no default"
        return m.group(2)

    return _VAR.sub(sub, text)


def argv(command: str | list[str]) -> list[str]:
    parts = shlex.split(command) if isinstance(command, str) else list(command)
    return [interpolate(p) for p in parts]


def health_argv(service: dict[str, Any]) -> list[str]:
    test = argv(service["healthcheck"]["test"])
    assert test[0] in ("CMD", "CMD-SHELL"), f"healthcheck test {test} must start with CMD or CMD-SHELL"
    return test[1:] if test[0] == "CMD" else shlex.split(test[1])


def router_config(path: Path) -> dict[str, Any]:
    """The router config as the Zenoh library reads it (unknown keys are errors there)."""
    return json.loads(str(zenoh.Config.from_file(str(path))))


# --- Dockerfiles -----------------------------------------------------------------------------------
@dataclass
class Package:
    root: Path
    extras: set[str]

    @functools.cached_property
    def project(self) -> dict[str, Any]:
        return tomllib.loads((self.root / "pyproject.toml").read_text())["project"]

    @property
    def name(self) -> str:
        return canonicalize_name(self.project["name"])

    def requirements(self) -> list[Requirement]:
        reqs = list(self.project.get("dependencies", []))
        for extra in self.extras:
            reqs += self.project.get("optional-dependencies", {})[extra]
        return [Requirement(r) for r in reqs]

    def entry_points(self) -> dict[str, str]:
        return dict(self.project.get("entry-points", {}).get("sofia.commands", {}))


@dataclass
class Image:
    dockerfile: Path
    base: str = ""
    user: str = "root"
    copies: list[tuple[str, str]] = field(default_factory=list)  # (container path, repo path)
    runs: list[str] = field(default_factory=list)
    cmd: list[str] = field(default_factory=list)
    pip_args: list[tuple[str, str]] = field(default_factory=list)  # (workdir, argument)

    def repo_path(self, container_path: str) -> Path:
        for dest, src in self.copies:
            if container_path == dest or container_path.startswith(dest + "/"):
                return REPO / src / posixpath.relpath(container_path, dest)
        raise AssertionError(f"{self.dockerfile.name}: {container_path} was not copied into the image")

    @functools.cached_property
    def packages(self) -> dict[str, Package]:
        pkgs = {}
        for workdir, arg in self.pip_args:
            m = re.fullmatch(r"(?P<path>[^\[]+)(\[(?P<extras>[^\]]*)\])?", arg)
            assert m and arg.startswith((".", "/")), (
                f"{self.dockerfile.name}: pip installs {arg!r} from an index"
            )
            root = self.repo_path(posixpath.normpath(posixpath.join(workdir, m["path"])))
            pkg = Package(root, {e.strip() for e in (m["extras"] or "").split(",") if e.strip()})
            pkgs[pkg.name] = pkg
        return pkgs


def _commands(run: str) -> list[list[str]]:
    """The words of each command of a shell line (split at ``&&``, ``||`` and ``;`` outside quotes)."""
    lexer = shlex.shlex(run, posix=True, punctuation_chars=True)
    lexer.whitespace_split = True
    commands: list[list[str]] = [[]]
    for token in lexer:
        if token in ("&&", "||", ";"):
            commands.append([])
        else:
            commands[-1].append(token)
    return [c for c in commands if c]


def parse_dockerfile(path: Path) -> Image:
    image, workdir = Image(path), "/"
    text = re.sub(
        r"\\\n", " ", "\n".join(ln for ln in path.read_text().splitlines() if not ln.strip().startswith("#"))
    )
    for line in filter(None, (ln.strip() for ln in text.splitlines())):
        op, _, rest = line.partition(" ")
        op, rest = op.upper(), rest.strip()
        if op == "FROM":
            image.base = rest.split()[0]
        elif op == "WORKDIR":
            workdir = posixpath.join(workdir, rest)
        elif op == "USER":
            image.user = rest.split(":")[0]
        elif op == "COPY":
            *sources, dest = [a for a in shlex.split(rest) if not a.startswith("--")]
            dest = posixpath.join(workdir, dest)
            for src in sources:
                is_dir = (REPO / src).is_dir()
                target = dest if is_dir or not dest.endswith("/") else posixpath.join(dest, Path(src).name)
                image.copies.append((posixpath.normpath(target), src.rstrip("/")))
        elif op == "CMD":
            image.cmd = json.loads(rest)
        elif op == "RUN":
            image.runs.append(rest)
            for words in _commands(rest):
                if "pip" in words[:3] and "install" in words:
                    args = words[words.index("install") + 1 :]
                    with_value = {"-c", "-r", "--constraint", "--requirement"}
                    for i, a in enumerate(args):
                        if a.startswith("-"):
                            if a in with_value:
                                image.repo_path(posixpath.join(workdir, args[i + 1]))  # copied in?
                            continue
                        if i and args[i - 1] in with_value:
                            continue
                        image.pip_args.append((workdir, a))
    return image


def image_of(name: str) -> Image:
    build = services()[name]["build"]
    return parse_dockerfile(REPO / build.get("context", ".") / build["dockerfile"])


def dependency_closure(image: Image) -> set[str]:
    """Every distribution name pip installs in ``image``, from the pyprojects and installed metadata."""
    todo = [(n, frozenset(p.extras)) for n, p in image.packages.items()]
    seen: set[tuple[str, frozenset[str]]] = set()
    while todo:
        name, extras = todo.pop()
        if (name, extras) in seen:
            continue
        seen.add((name, extras))
        if name in image.packages:
            reqs = image.packages[name].requirements()
        else:
            try:
                reqs = [Requirement(r) for r in distribution(name).requires or []]
            except PackageNotFoundError:
                continue
            reqs = [
                r
                for r in reqs
                if r.marker is None or any(r.marker.evaluate({"extra": e}) for e in extras | {""})
            ]
        todo += [(canonicalize_name(r.name), frozenset(r.extras)) for r in reqs]
    return {name for name, _ in seen}


# Runs in a fresh interpreter where modules of distributions the image lacks cannot be imported:
# builds `sofia`'s parser from the image's entry points as cli.py does, prints which package
# registered which subcommands, then parses each command (exit 2 and the usage error if one fails).
_PROBE = """
import argparse, importlib.abc, json, sys
from importlib.metadata import EntryPoint

absent, entry_points, commands = json.loads(sys.argv[1])


class Absent(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.partition(".")[0] in absent:
            raise ModuleNotFoundError(f"No module named {name!r} (not in this image)", name=name)


sys.meta_path.insert(0, Absent())
parser = argparse.ArgumentParser(prog="sofia")
parser.add_argument("--log-level")
sub = parser.add_subparsers(dest="command", required=True)
owners = {}
for package, name, value in entry_points:
    before = set(sub.choices)
    try:
        EntryPoint(name, value, "sofia.commands").load()(sub)
    except ImportError as e:
        print(f"entry point {name} = {value} left out: {e}", file=sys.stderr)
    owners.setdefault(package, []).extend(sorted(set(sub.choices) - before))
print(json.dumps(owners), flush=True)
for argv in commands:
    assert callable(parser.parse_args(argv).func), argv
"""


@dataclass
class Probe:
    returncode: int
    owners: dict[str, list[str]]  # package -> the subcommands its entry points registered
    stderr: str


def start_probe(image: Image, commands: list[list[str]]) -> subprocess.Popen[str]:
    """Start :data:`_PROBE` for ``image`` with ``commands`` (argv without ``sofia``)."""
    closure = dependency_closure(image)
    absent = [
        m for m, ds in packages_distributions().items() if not {canonicalize_name(d) for d in ds} & closure
    ]
    entry_points = [(p.name, *ep) for p in image.packages.values() for ep in p.entry_points().items()]
    arg = json.dumps([absent, entry_points, commands])
    return subprocess.Popen([sys.executable, "-c", _PROBE, arg], stdout=PIPE, stderr=PIPE, text=True)


def finish_probe(proc: subprocess.Popen[str]) -> Probe:
    out, err = proc.communicate(timeout=120)
    lines = out.splitlines()
    return Probe(proc.returncode, json.loads(lines[0]) if lines else {}, err)


@functools.cache
def image_probes() -> dict[str, Probe]:
    """One probe per Dockerfile, with the commands and healthchecks of every service built from it,
    run side by side."""
    commands: dict[str, list[list[str]]] = {}
    for name in SOFIA_SERVICES:
        cmds = commands.setdefault(services()[name]["build"]["dockerfile"], [])
        cmds += [argv(services()[name]["command"])[1:], health_argv(services()[name])[1:]]
    first = {services()[n]["build"]["dockerfile"]: n for n in reversed(SOFIA_SERVICES)}
    images = {df: image_of(name) for df, name in first.items()}
    for df, image in images.items():  # the image's own CMD, for `docker run` without compose
        assert image.cmd[:1] == ["sofia"], f"{df}: CMD {image.cmd} does not run sofia"
        commands[df].append(image.cmd[1:])
    procs = {df: start_probe(images[df], cmds) for df, cmds in commands.items()}
    return {df: finish_probe(proc) for df, proc in procs.items()}


def probe_of(name: str) -> Probe:
    return image_probes()[services()[name]["build"]["dockerfile"]]


def dockerignored(path: str) -> bool:
    """Whether a build-context path is excluded by .dockerignore (its ``X`` and ``**/X`` patterns)."""
    parts = Path(path).parts
    for pat in (p.strip() for p in (REPO / ".dockerignore").read_text().splitlines()):
        if not pat or pat.startswith("#"):
            continue
        if pat.startswith("**/"):
            if any(fnmatch.fnmatch(part, pat[3:]) for part in parts):
                return True
        elif any(fnmatch.fnmatch("/".join(parts[: i + 1]), pat.strip("/")) for i in range(len(parts))):
            return True
    return False


# --- the compose file --------------------------------------------------------------------------------
@functools.cache
def validator() -> jsonschema.Draft7Validator:
    schema = json.loads(SCHEMA.read_text())
    jsonschema.Draft7Validator.check_schema(schema)
    return jsonschema.Draft7Validator(schema)


def schema_errors(doc: dict[str, Any]) -> list[str]:
    return [f"{'/'.join(map(str, e.absolute_path))}: {e.message}" for e in validator().iter_errors(doc)]


def mounts(service: dict[str, Any]) -> dict[str, str]:
    """Container path -> host path (or volume name) of a service's volumes."""
    return {v.split(":")[1]: v.split(":")[0] for v in map(interpolate, service.get("volumes", []))}


def test_compose_file_follows_the_compose_specification() -> None:
    assert schema_errors(compose()) == []


@pytest.mark.parametrize(
    ("path", "value"),
    [
        (("services", "detector", "restart"), 5),  # wrong type
        (("services", "detector", "healtcheck"), {"test": ["CMD", "true"]}),  # misspelt key
        (("services", "replay", "depends_on", "zenoh", "condition"), "service_ready"),  # not in enum
        (("volumes", "sofia state"), None),  # invalid name
    ],
)
def test_the_schema_rejects_a_broken_compose_file(path: tuple[str, ...], value: Any) -> None:
    doc = copy.deepcopy(compose())
    node = doc
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    assert schema_errors(doc), f"setting {'/'.join(path)} = {value!r} went unnoticed"


def test_router_is_the_official_image_pinned_to_1x_with_its_config_mounted() -> None:
    router = services()[ROUTER]
    assert re.fullmatch(r"eclipse/zenoh:1\.\d+\.\d+", router["image"]), router["image"]
    command = argv(router["command"])
    config_in_container = command[command.index("-c") + 1]
    config = router_config(REPO / mounts(router)[config_in_container])
    assert config["mode"] == "router"
    assert config["listen"]["endpoints"] == ["tcp/[::]:7447"]
    assert config["scouting"]["multicast"]["enabled"] is False
    assert config["adminspace"]["enabled"] is True and config["adminspace"]["permissions"]["write"] is False
    # the healthcheck reads the admin space through the REST plugin, reachable only in the container
    rest = config["plugins"]["rest"]["http_port"]
    assert rest.startswith("127.0.0.1:"), rest
    health = health_argv(router)
    assert any(a.startswith(f"http://{rest}/@/") for a in health), health
    published = [interpolate(p) for p in router["ports"]]
    assert published == ["127.0.0.1:7447:7447"], "by default the bus is published on the host's loopback only"


def test_secure_router_and_client_configs_load_in_zenoh() -> None:
    router = router_config(REPO / "docker/zenoh/router-secure.json5")
    assert router["listen"]["endpoints"] == ["tls/[::]:7447"]
    tls = router["transport"]["link"]["tls"]
    assert tls["enable_mtls"] is True and tls["listen_certificate"] and tls["listen_private_key"]
    assert router["transport"]["auth"]["usrpwd"]["dictionary_file"]
    client = router_config(REPO / "docker/zenoh/client-secure.json5")
    assert client["mode"] == "client" and client["connect"]["endpoints"][0].startswith("tls/")
    assert client["transport"]["link"]["tls"]["connect_certificate"]
    assert client["transport"]["auth"]["usrpwd"]["user"]
    with pytest.raises(Exception, match="listen_certificat"):  # the library does check the keys
        zenoh.Config.from_json5('{transport: {link: {tls: {listen_certificat: "/x"}}}}')


def test_the_secure_overlay_puts_every_service_on_tls_with_credentials(tmp_path: Path) -> None:
    overlay = yaml.safe_load((REPO / "docker/compose.secure.yaml").read_text())
    assert schema_errors(overlay) == []
    assert set(overlay["services"]) == set(services()), "every service of compose.yaml is covered"
    router_config_path = argv(services()[ROUTER]["command"])[-1]
    router_mounts = mounts(overlay["services"][ROUTER])
    assert router_mounts[router_config_path] == "./docker/zenoh/router-secure.json5"
    tls = router_config(REPO / router_mounts[router_config_path])["transport"]["link"]["tls"]
    assert tls["listen_certificate"].startswith(next(t for t, s in router_mounts.items() if s == "./certs"))
    for name in SOFIA_SERVICES:
        service = overlay["services"][name]
        env = {
            k: interpolate(str(v))
            for k, v in {**services()[name]["environment"], **service["environment"]}.items()
        }
        config = mounts(service)[env["SOFIA_ZENOH_CONFIG"]]
        assert config == "./docker/zenoh/client-secure.json5", name
        env["SOFIA_ZENOH_CONFIG"] = str(REPO / config)  # the host copy of the mounted file
        assert env["SOFIA_ZENOH_USER"] == name.removesuffix("-emulated"), "each service its own identity"
        (tmp_path / "pw").write_text("a password\n")  # stands for /etc/sofia/certs/<user>.password
        env["SOFIA_ZENOH_PASSWORD_FILE"] = str(tmp_path / "pw")
        settings = resolve(env=env)
        assert settings["connect"] == [f"tls/{ROUTER}:7447"] and settings["mode"] == "client"
        zenoh_config(env=env)  # the service's own helper builds a valid Zenoh config from it
        client_tls = router_config(REPO / config)["transport"]["link"]["tls"]
        certs = next(t for t, s in mounts(service).items() if s == "./certs")
        assert all(
            client_tls[k].startswith(certs + "/") for k in ("root_ca_certificate", "connect_certificate")
        )


@pytest.mark.parametrize("name", list(services()))
def test_every_service_restarts_and_has_a_healthcheck(name: str) -> None:
    service = services()[name]
    assert service.get("restart") in RESTART_POLICIES, f"{name}: restart is {service.get('restart')!r}"
    health = service.get("healthcheck", {})
    assert not health.get("disable") and health_argv(service), f"{name} has no healthcheck"


@pytest.mark.parametrize("name", SOFIA_SERVICES)
def test_every_sofia_service_connects_to_the_router_by_tcp(name: str) -> None:
    service = services()[name]
    env = {k: interpolate(str(v)) for k, v in service["environment"].items()}
    port = router_config(REPO / "docker/zenoh/router.json5")["listen"]["endpoints"][0].rsplit(":", 1)[1]
    assert env["SOFIA_ZENOH_CONNECT"] == f"tcp/{ROUTER}:{port}"
    assert env["SOFIA_ROBOT"] == "panda"
    settings = resolve(env=env)  # what the service's own Zenoh helper makes of that environment
    assert settings["connect"] == [f"tcp/{ROUTER}:{port}"] and settings["multicast"] is False
    assert settings["mode"] == "client" and settings["listen"] == []
    assert service["depends_on"] == {ROUTER: {"condition": "service_healthy"}}


@pytest.mark.parametrize("name", SOFIA_SERVICES)
def test_healthcheck_asks_for_the_service_own_status(name: str) -> None:
    service = services()[name]
    status_of = argv(service["command"])[1]  # detector, calibrator, gripper, replay
    key = Keys(interpolate(service["environment"]["SOFIA_ROBOT"])).status(status_of)
    health = health_argv(service)
    # degraded (e.g. a detector before its first calibration) still serves: healthy for Docker
    assert health == ["sofia", "health", status_of, "--degraded-ok"], (
        f"{name}: healthcheck {health} does not ask for {key}"
    )


def test_profiles_keep_the_optional_services_off_by_default() -> None:
    profiles = {name: s.get("profiles", []) for name, s in services().items()}
    assert profiles == {
        "zenoh": [], "detector": [], "calibrator": [],
        "gripper": ["gripper"], "gripper-emulated": ["emulate"], "replay": ["replay"], "camera": ["robot"],
        "arm": ["robot"], "ros2": [], "viz": ["viz"],
    }  # fmt: skip


def test_the_gripper_gets_the_serial_device_and_the_emulated_one_does_not() -> None:
    gripper, emulated = services()["gripper"], services()["gripper-emulated"]
    host, container = interpolate(gripper["devices"][0]).split(":")[:2]
    assert host == "/dev/ttyUSB0"
    command = argv(gripper["command"])
    assert command[command.index("--port") + 1] == container
    assert "dialout" in gripper["group_add"]
    assert "--emulate" in argv(emulated["command"]) and "devices" not in emulated


def test_mounts_state_volume_board_and_recordings() -> None:
    named = set(compose()["volumes"])
    for name, service in services().items():
        for volume in map(interpolate, service.get("volumes", [])):
            source = volume.split(":")[0]
            if source.startswith("."):
                assert source == "./recordings" or (REPO / source).exists(), f"{name}: {source} missing"
            else:
                assert source in named, f"{name}: volume {source} is not declared"
    calibrator = services()["calibrator"]
    state = next(target for target, source in mounts(calibrator).items() if source in named)
    command = argv(calibrator["command"])
    for path in (command[command.index("--state-dir") + 1], calibrator["working_dir"]):
        assert path.startswith(state + "/"), f"the calibrator's {path} is outside the named volume {state}"
    assert "./config/board.yaml:/etc/sofia/board.yaml:ro" in services()["detector"]["volumes"]
    replay = services()["replay"]
    assert "./recordings:/recordings:ro" in map(interpolate, replay["volumes"])
    assert argv(replay["command"])[3].startswith("/recordings/") and "--loop" in argv(replay["command"])


CLOUD_SERVICES = ("detector", "replay", "camera", "ros2", "viz")  # publish or subscribe to clouds
SIZE_UNITS = {"k": 1 << 10, "m": 1 << 20, "g": 1 << 30}


def test_cloud_services_share_the_routers_dev_shm_sized_for_the_pools() -> None:
    """Zenoh shared memory in compose: the services that move clouds join the router's IPC
    namespace (and /dev/shm), whose size holds the camera's and the replayer's pools at 1280x720
    plus each session's own transport pool; both router configs enable it; on by default."""
    router = services()[ROUTER]
    assert router["ipc"] == "shareable"
    for name in CLOUD_SERVICES:
        assert services()[name]["ipc"] == f"service:{ROUTER}", f"{name} has its own /dev/shm"
    size = str(router["shm_size"]).lower()
    shm_bytes = int(size[:-1]) * SIZE_UNITS[size[-1]] if size[-1] in SIZE_UNITS else int(size)
    from sofia_camera.shm import SHM_RESERVE
    from sofia_replay.preload import ShmBuffers
    from sofia_schemas import pointcloud

    cloud = len(pointcloud.encode_points(np.zeros((720, 1280, 3), np.float32), stamp_ns=0,
                                         frame_id="camera", rgb=np.zeros((720, 1280, 3), np.uint8)))  # fmt: skip
    pools = 2 * ShmBuffers.POOL_MESSAGES * cloud + SHM_RESERVE * len(SOFIA_SERVICES)
    assert shm_bytes >= pools, f"shm_size {size} < {pools / 1e6:.0f} MB of pools"
    for config in ("router.json5", "router-secure.json5"):
        assert router_config(REPO / "docker/zenoh" / config)["transport"]["shared_memory"]["enabled"] is True
    env = {k: interpolate(str(v)) for k, v in services()["detector"]["environment"].items()}
    assert env["SOFIA_ZENOH_SHM"] == "on"
    assert json.loads(str(zenoh_config(env=env)))["transport"]["shared_memory"]["enabled"] is True
    off = json.loads(str(zenoh_config(env={**env, "SOFIA_ZENOH_SHM": "off"})))
    assert off["transport"]["shared_memory"]["enabled"] is False


@pytest.mark.parametrize("shm", ["on", "off"])
def test_clouds_cross_the_router_by_shared_memory_as_in_compose(
    sofia_proc: Callable[..., Any], robot_id: str, tmp_path: Path, shm: str
) -> None:
    """The compose wiring without Docker: a router, the replay service as its client by TCP with the
    compose environment, and a subscriber that is another client of it: the clouds reach the
    subscriber as shared-memory buffers through the router, byte for byte; with
    ``SOFIA_ZENOH_SHM=off`` (the compose switch) as bytes."""
    from sofia_replay.mcap_io import McapWriter
    from sofia_schemas import pointcloud
    from sofia_schemas.keys import TOPIC_POINTS

    rng = np.random.default_rng(3)
    rec, written = tmp_path / "scenes.mcap", []
    with McapWriter(rec) as w:
        for i in range(4):
            cloud = bytes(pointcloud.encode_points(rng.normal(size=(96, 128, 3)).astype(np.float32),
                                                   stamp_ns=i + 1, frame_id="panda_link0"))  # fmt: skip
            w.write_cloud(TOPIC_POINTS, cloud, i + 1)
            written.append(cloud)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    sofia_proc("router", "--listen", f"tcp/127.0.0.1:{port}").wait_for_log("router ready")
    service = services()["replay"]
    env = {k: interpolate(str(v)) for k, v in service["environment"].items()}
    env.update(SOFIA_ROBOT=robot_id, SOFIA_ZENOH_CONNECT=f"tcp/127.0.0.1:{port}")  # host "zenoh" here
    if shm == "off":
        env["SOFIA_ZENOH_SHM"] = "off"
    via_shm: list[bool] = []
    payloads: list[bytes] = []

    def on_cloud(sample: zenoh.Sample) -> None:
        via_shm.append(sample.payload.as_shm() is not None)
        payloads.append(sample.payload.to_bytes())

    with zenoh.open(zenoh_config(env={**env, "SOFIA_ZENOH_SHM": "on"})) as session:
        session.declare_subscriber(Keys(robot_id).points, on_cloud)
        command = [str(rec) if a.startswith("/recordings/") else a for a in argv(service["command"])[1:]]
        command.remove("--loop")
        replay = sofia_proc(*command, "--topic", TOPIC_POINTS, "--wait-subscribers", "20", env=env)
        assert replay.popen.wait(60) == 0, replay.log()
        deadline = time.monotonic() + 10
        while len(payloads) < len(written) and time.monotonic() < deadline:
            time.sleep(0.02)
    assert payloads == written
    if shm == "off":
        assert not any(via_shm)
    else:  # from the first cloud on (a pool whose 4 buffers are all still held falls back to bytes)
        assert via_shm[0] and sum(via_shm) >= len(written) - 1, via_shm


# --- the images --------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", BUILT_SERVICES)
def test_dockerfile_base_user_and_copies(name: str) -> None:
    image = image_of(name)
    assert image.base == "python:3.11-slim"
    assert image.user not in ("root", "0"), f"{image.dockerfile.name} runs as root"
    assert image.copies, f"{image.dockerfile.name} copies nothing"
    for _, src in image.copies:
        assert (REPO / src).exists(), f"{image.dockerfile.name}: COPY {src} does not exist"
        assert not dockerignored(src), f"{image.dockerfile.name}: COPY {src} is excluded by .dockerignore"


@pytest.mark.parametrize("name", SOFIA_SERVICES)
def test_image_installs_exactly_the_packages_its_command_needs(name: str) -> None:
    image, probe = image_of(name), probe_of(name)
    command, health = argv(services()[name]["command"]), health_argv(services()[name])
    assert command[0] == health[0] == "sofia"
    assert any(p.project.get("scripts", {}).get("sofia") for p in image.packages.values())
    for sub in (command[1], health[1]):
        assert any(sub in subs for subs in probe.owners.values()), (
            f"{name}: no package of {image.dockerfile.name} registers `sofia {sub}`\n{probe.stderr}"
        )
    owner = next(p for p, subs in probe.owners.items() if command[1] in subs)
    needed, todo = set(), [owner]
    while todo:  # the SofIA packages the command's package depends on must come from the repository
        pkg = image.packages.get(todo.pop())
        assert pkg is not None, f"{image.dockerfile.name} lacks a SofIA dependency of {owner}"
        needed.add(pkg.name)
        todo += [canonicalize_name(r.name) for r in pkg.requirements() if r.name.startswith("sofia-")]
    assert set(image.packages) == needed, (
        f"{image.dockerfile.name} installs more than `sofia {command[1]}` needs"
    )


@pytest.mark.parametrize("name", SOFIA_SERVICES)
def test_command_and_healthcheck_parse_with_only_what_the_image_installs(name: str) -> None:
    probe = probe_of(name)
    assert probe.returncode == 0, f"{name}: command or healthcheck fails in its image:\n{probe.stderr}"


def test_the_probe_fails_without_the_needed_package() -> None:
    image = image_of("gripper")
    del image.packages["sofia-gripper"]  # as if the Dockerfile forgot it
    probe = finish_probe(start_probe(image, [["health", "gripper"], ["gripper", "serve", "--emulate"]]))
    assert "health" in probe.owners["sofia-runtime"] and "sofia-gripper" not in probe.owners
    assert probe.returncode == 2 and "invalid choice: 'gripper'" in probe.stderr, probe.stderr


def test_gripper_image_pulls_no_open3d_while_the_detector_needs_it() -> None:
    gripper = dependency_closure(image_of("gripper"))
    assert {"sofia-gripper", "sofia-runtime", "dynamixel-sdk", "eclipse-zenoh"} <= gripper
    assert "open3d" not in gripper, "the gripper image would install open3d"
    assert "scipy" not in gripper, "the gripper image would install scipy"
    detector = image_of("detector")
    assert "open3d" in dependency_closure(detector)  # so the check above can fail
    apt = next(r for r in detector.runs if "apt-get install" in r)
    assert {"libusb-1.0-0", "libgomp1"} <= set(apt.split()), "Open3D needs libusb-1.0-0 and libgomp1"


def test_the_emulated_gripper_becomes_healthy_through_a_router_as_in_compose(
    sofia_proc: Callable[..., Any], robot_id: str
) -> None:
    """The compose wiring without Docker: a router, the gripper-emulated service as a Zenoh client
    of it by TCP with the compose environment, and the compose healthcheck exiting 0."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    service = services()["gripper-emulated"]
    env = {k: interpolate(str(v)) for k, v in service["environment"].items()}
    env.update(SOFIA_ROBOT=robot_id, SOFIA_ZENOH_CONNECT=f"tcp/127.0.0.1:{port}")  # host "zenoh" here
    sofia_proc("router", "--listen", f"tcp/127.0.0.1:{port}").wait_for_log("router ready")
    gripper = sofia_proc(*argv(service["command"])[1:], env=env)
    health = health_argv(service)
    deadline = time.monotonic() + 30
    while True:
        run = subprocess.run([SOFIA, *health[1:]], env={**os.environ, **env}, capture_output=True, text=True)
        if run.returncode == 0 or time.monotonic() > deadline:
            break
        time.sleep(0.2)
    assert run.returncode == 0, f"{health} exited {run.returncode}: {run.stderr}\n{gripper.log()}"
    assert "gripper:" in run.stdout
