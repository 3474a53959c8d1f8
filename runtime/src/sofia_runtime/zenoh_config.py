"""One helper builds the Zenoh session config of every SofIA process.

Precedence, lowest first:

1. defaults: one user's bus. Peer mode; each session listens on a Unix socket
   (``unixsock-stream``) in a directory only this user can enter (mode 0700, see
   :func:`socket_dir`) and connects to the sockets already there, so processes of this user on
   one machine find each other with no router and no network link. No multicast scouting: no
   HELLO of another user's peer (or a forged one) is heard, and no UDP socket is open. Another
   user can neither enter the directory nor be dialled. A router's default listener is such a
   socket too (``local``); TCP only where asked (``--listen tcp/...``, and ``sofia up --ros2``,
   which opens ``tcp/127.0.0.1:7447`` to rmw_zenoh nodes: every local user can then reach the
   router; ``sofia ros2 serve`` also listens on a loopback port, see
   :func:`sofia_runtime.ros2.service.bridge_options`);
2. a json5 Zenoh config file: ``--zenoh-config FILE`` or ``$SOFIA_ZENOH_CONFIG``;
3. environment: ``$SOFIA_ZENOH_MODE`` (peer|client|router), ``$SOFIA_ZENOH_CONNECT`` and
   ``$SOFIA_ZENOH_LISTEN`` (comma-separated endpoints, e.g. ``tcp/zenoh:7447``);
4. command-line flags: ``--zenoh-mode``, ``--connect``, ``--listen``.

When connect endpoints are given (a router, as in compose), discovery goes through the router and
this user's sockets are not dialled. Whenever
the session has connect endpoints, whatever their source (a config file included), it waits for
them when they are not reachable yet, rather than failing, and reconnects by itself after a router
restart (a config file that sets ``connect/timeout_ms``, ``exit_on_failure`` or ``retry`` keeps its
own values). Explicit ``--listen`` endpoints without connect endpoints keep the local sockets too;
their protocols are then allowed, and anyone who can reach them joins: on shared machines or
untrusted networks use the secure router (docker/zenoh/router-secure.json5).

Zenoh shared memory (payloads over 3 KB to processes on the same host through ``/dev/shm``) is on
unless ``$SOFIA_ZENOH_SHM=off``.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import secrets
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import zenoh

log = logging.getLogger(__name__)
ENV_CONFIG = "SOFIA_ZENOH_CONFIG"
ENV_MODE = "SOFIA_ZENOH_MODE"
ENV_CONNECT = "SOFIA_ZENOH_CONNECT"
ENV_LISTEN = "SOFIA_ZENOH_LISTEN"
ENV_SOCKET_DIR = "SOFIA_ZENOH_SOCKET_DIR"
ENV_USER = "SOFIA_ZENOH_USER"
ENV_PASSWORD_FILE = "SOFIA_ZENOH_PASSWORD_FILE"
ENV_SHM = "SOFIA_ZENOH_SHM"  # "off" (or 0/false/no): no Zenoh shared memory; default on
LOCAL = "local"  # as a listen endpoint: this session's socket in the user's socket directory
DEFAULT_ROUTER_LISTEN = [LOCAL]
ROS2_ROUTER_LISTEN = "tcp/127.0.0.1:7447"  # where rmw_zenoh nodes look for a router (sofia up --ros2)
LOCAL_PROTOCOL = "unixsock-stream"
MODES = ("peer", "client", "router")
CONNECT_TIMEOUT_MS = {"router": -1, "peer": -1, "client": -1}
EXIT_ON_FAILURE = {"router": False, "peer": False, "client": False}
CONNECT_RETRY = {"period_init_ms": 250, "period_max_ms": 2000, "period_increase_factor": 1.5}
WAIT_SETTINGS = {"connect/timeout_ms": CONNECT_TIMEOUT_MS, "connect/exit_on_failure": EXIT_ON_FAILURE,
                 "connect/retry": CONNECT_RETRY}  # fmt: skip


def _split(value: str | None) -> list[str]:
    return [v.strip() for v in value.split(",") if v.strip()] if value else []


def socket_dir(env: dict[str, str] | None = None) -> Path:
    """The directory of this user's local (Unix socket) endpoints, mode 0700: ``$SOFIA_ZENOH_SOCKET_DIR``,
    else ``$XDG_RUNTIME_DIR/sofia-zenoh``, else ``<tmp>/sofia-zenoh-<uid>``."""
    env = dict(os.environ if env is None else env)
    if env.get(ENV_SOCKET_DIR):
        path = Path(env[ENV_SOCKET_DIR])
    elif env.get("XDG_RUNTIME_DIR") and os.access(env["XDG_RUNTIME_DIR"], os.W_OK):
        path = Path(env["XDG_RUNTIME_DIR"]) / "sofia-zenoh"
    else:
        path = Path(tempfile.gettempdir()) / f"sofia-zenoh-{os.getuid()}"
    path.mkdir(mode=0o700, parents=True, exist_ok=True)
    return path


def _prune(directory: Path) -> None:
    """Remove sockets left by processes that died without closing their session (``<pid>-*.sock``)."""
    for sock in directory.glob("*-*.sock"):
        pid = sock.name.split("-", 1)[0]
        if pid.isdigit() and not Path(f"/proc/{pid}").exists():
            sock.unlink(missing_ok=True)


def local_endpoint(env: dict[str, str] | None = None) -> str:
    """A fresh Unix-socket endpoint for one session (``unixsock-stream/<dir>/<pid>-<random>.sock``)."""
    directory = socket_dir(env)
    _prune(directory)
    return f"{LOCAL_PROTOCOL}/{directory}/{os.getpid()}-{secrets.token_hex(4)}.sock"


def local_peers(own: str | None, env: dict[str, str] | None = None) -> list[str]:
    """The endpoints of this user's other sessions on this machine (their sockets, oldest first)."""
    directory = socket_dir(env)
    socks = sorted(directory.glob("*-*.sock"), key=lambda p: p.stat().st_mtime if p.exists() else 0.0)
    endpoints = [f"{LOCAL_PROTOCOL}/{p}" for p in socks]
    return [e for e in endpoints if e != own]


def wait_for_socket(
    proc: subprocess.Popen[bytes], timeout_s: float, env: dict[str, str] | None = None
) -> bool:
    """Wait until the process ``proc`` listens on its local socket (``<pid>-*.sock`` in
    :func:`socket_dir`): True once it does, and at once when sessions here do not use local
    sockets (a config file, connect endpoints, client mode); False after ``timeout_s`` or when
    the process has ended."""
    settings = resolve(None, env)
    if settings["config_file"] or settings["connect"] or settings["mode"] == "client":
        return True
    directory, deadline = socket_dir(env), time.monotonic() + timeout_s
    while not any(directory.glob(f"{proc.pid}-*.sock")):
        if time.monotonic() > deadline or proc.poll() is not None:
            return False
        time.sleep(0.05)
    return True


def _protocol(endpoint: str) -> str:
    return endpoint.split("/", 1)[0]


@dataclass
class ZenohOptions:
    """Where a session connects and listens. ``None`` means "not set at this level"."""

    mode: str | None = None
    connect: list[str] = field(default_factory=list)
    listen: list[str] = field(default_factory=list)
    config_file: str | None = None

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> ZenohOptions:
        return cls(getattr(args, "zenoh_mode", None), list(getattr(args, "connect", None) or []),
                   list(getattr(args, "listen", None) or []), getattr(args, "zenoh_config", None))  # fmt: skip


def add_zenoh_args(parser: argparse.ArgumentParser) -> None:
    """Add ``--zenoh-mode``, ``--connect``, ``--listen``, ``--zenoh-config`` to a parser."""
    g = parser.add_argument_group("zenoh")
    g.add_argument("--zenoh-mode", choices=MODES, default=None,
                   help="session mode (default $SOFIA_ZENOH_MODE, else peer)")  # fmt: skip
    g.add_argument("--connect", action="append", metavar="ENDPOINT",
                   help="connect to this endpoint, e.g. tcp/127.0.0.1:7447; repeatable "
                   "(default $SOFIA_ZENOH_CONNECT, else this user's local sockets)")  # fmt: skip
    g.add_argument("--listen", action="append", metavar="ENDPOINT",
                   help="listen on this endpoint too, e.g. tcp/127.0.0.1:0; repeatable "
                   "(default $SOFIA_ZENOH_LISTEN, else a socket in this user's socket directory)")  # fmt: skip
    g.add_argument("--zenoh-config", metavar="FILE",
                   help="json5 Zenoh config file (default $SOFIA_ZENOH_CONFIG, else none)")  # fmt: skip


def _explicit(options: ZenohOptions, env: dict[str, str]) -> dict[str, object]:
    """Settings given by flags (level 4) or, failing that, the environment (level 3)."""
    mode = options.mode or env.get(ENV_MODE)
    if mode and mode not in MODES:
        raise ValueError(f"Zenoh mode {mode!r} is not one of {MODES}")
    given = {"mode": mode, "connect": options.connect or _split(env.get(ENV_CONNECT)),
             "listen": options.listen or _split(env.get(ENV_LISTEN))}  # fmt: skip
    return {name: value for name, value in given.items() if value}


def resolve(options: ZenohOptions | None = None, env: dict[str, str] | None = None) -> dict[str, object]:
    """The effective settings as a dict: mode, connect, listen, config_file, multicast, protocols
    (the link protocols the session may use; None: Zenoh's default, all).

    With a config file, values not overridden by the environment or flags come from the file.
    """
    options = options or ZenohOptions()
    env = dict(os.environ if env is None else env)
    config_file = options.config_file or env.get(ENV_CONFIG)
    if config_file and not Path(config_file).is_file():
        raise FileNotFoundError(f"Zenoh config file {config_file!r} does not exist")
    explicit = _explicit(options, env)
    if config_file:
        conf = zenoh.Config.from_file(config_file)

        def get(key: str) -> object:
            return json.loads(conf.get_json(key))

        multicast = get("scouting/multicast/enabled")
        base: dict[str, object] = {
            "mode": get("mode") or "peer",
            "connect": get("connect/endpoints") or [],
            "listen": get("listen/endpoints") or [],
            "multicast": True if multicast is None else bool(multicast),  # Zenoh's default is on
            "protocols": get("transport/link/protocols"),
        }
        base.update(explicit)
        return {**base, "config_file": config_file}
    mode = str(explicit.get("mode", "peer"))
    connect = list(explicit.get("connect", []))  # type: ignore[call-overload]
    listen = list(explicit.get("listen", []))  # type: ignore[call-overload]
    if not listen and mode == "router":
        listen = list(DEFAULT_ROUTER_LISTEN)
    protocols, peers = None, []
    listen = [e for e in listen if e != LOCAL]  # "local": the socket added below
    if not connect:  # this user's sockets only, plus the protocols of explicit listeners
        own = local_endpoint(env) if mode != "client" else None
        listen += [own] if own else []
        peers = local_peers(own, env)
        protocols = list(dict.fromkeys([LOCAL_PROTOCOL, *(_protocol(e) for e in listen)]))
    return dict(mode=mode, connect=connect, listen=listen, config_file=None, multicast=False, protocols=protocols,
                local_peers=peers)  # fmt: skip


def _wait_for_connect(conf: zenoh.Config) -> None:
    """With connect endpoints, wait for them instead of failing when they are not up yet (or
    restarting), retrying every 0.25 s to 2 s; settings a config file gives explicitly are kept."""
    connect = json.loads(conf.get_json("connect/endpoints"))
    if not connect:
        return
    log.info("connecting to %s (waiting until reachable)", connect)
    for path, value in WAIT_SETTINGS.items():
        if json.loads(conf.get_json(path)) is None:
            conf.insert_json5(path, json.dumps(value))


def _apply_user(conf: zenoh.Config, env: dict[str, str]) -> None:
    """``$SOFIA_ZENOH_USER`` and the first line of ``$SOFIA_ZENOH_PASSWORD_FILE``: the identity
    (``transport/auth/usrpwd``) a router's access control knows this process by."""
    user = env.get(ENV_USER)
    if not user:
        return
    path = env.get(ENV_PASSWORD_FILE)
    if not path or not Path(path).is_file():
        raise FileNotFoundError(f"${ENV_USER} is set but ${ENV_PASSWORD_FILE} ({path!r}) is not a file")
    lines = Path(path).read_text().splitlines()
    password = lines[0].strip() if lines else ""
    if not password:
        raise ValueError(f"password file {path!r} (${ENV_PASSWORD_FILE}) is empty")
    conf.insert_json5("transport/auth/usrpwd/user", json.dumps(user))
    conf.insert_json5("transport/auth/usrpwd/password", json.dumps(password))


def shm_wanted(env: dict[str, str] | None = None) -> bool:
    """False when ``$SOFIA_ZENOH_SHM`` is ``off`` (or 0, false, no): Zenoh shared memory is on by default."""
    value = (os.environ if env is None else env).get(ENV_SHM, "").strip().lower()
    return value not in ("off", "0", "false", "no")


def _apply_shm(conf: zenoh.Config, env: dict[str, str], default: bool) -> None:
    """Zenoh shared memory: payloads over 3 KB to a process on the same host travel through a pool
    in ``/dev/shm`` instead of the socket (a peer that cannot map it gets them over the link).
    ``$SOFIA_ZENOH_SHM=off`` turns it off; unset: on, or the config file's setting (``default``
    False)."""
    if env.get(ENV_SHM, "").strip() or default:
        conf.insert_json5("transport/shared_memory/enabled", json.dumps(shm_wanted(env)))


def zenoh_config(options: ZenohOptions | None = None, env: dict[str, str] | None = None) -> zenoh.Config:
    """Build the :class:`zenoh.Config` of a SofIA process (see the module docstring)."""
    options = options or ZenohOptions()
    env = dict(os.environ if env is None else env)
    s = resolve(options, env)
    if s["config_file"]:
        # the file is level 2: only what the environment or flags set overrides it
        conf = zenoh.Config.from_file(str(s["config_file"]))
        explicit = _explicit(options, env)
        for name, path in (
            ("mode", "mode"),
            ("connect", "connect/endpoints"),
            ("listen", "listen/endpoints"),
        ):
            if name in explicit:
                conf.insert_json5(path, json.dumps(explicit[name]))
        _wait_for_connect(conf)
        _apply_user(conf, env)
        _apply_shm(conf, env, default=False)
        return conf
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(s["mode"]))
    for name, path in (("connect", "connect/endpoints"), ("listen", "listen/endpoints"),
                       ("protocols", "transport/link/protocols")):  # fmt: skip
        if s[name]:
            conf.insert_json5(path, json.dumps(s[name]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    if s["local_peers"]:  # this user's sessions: dialled now, those gone are not waited for
        conf.insert_json5("connect/endpoints", json.dumps(s["local_peers"]))
        conf.insert_json5("connect/timeout_ms", json.dumps({"router": 0, "peer": 0, "client": 0}))
        conf.insert_json5("connect/exit_on_failure", json.dumps(EXIT_ON_FAILURE))
    else:
        _wait_for_connect(conf)
    _apply_user(conf, env)
    _apply_shm(conf, env, default=True)
    return conf


def open_session(options: ZenohOptions | None = None) -> zenoh.Session:
    """Open a Zenoh session with :func:`zenoh_config`."""
    return zenoh.open(zenoh_config(options))
