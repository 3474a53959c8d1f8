"""One helper builds the Zenoh session config of every SofIA process.

Precedence, lowest first:

1. defaults: peer mode, listening on loopback only (``tcp/127.0.0.1:0``), multicast scouting on
   the loopback interface, so processes on one machine find each other with no router;
2. a json5 Zenoh config file: ``--zenoh-config FILE`` or ``$SOFIA_ZENOH_CONFIG``;
3. environment: ``$SOFIA_ZENOH_MODE`` (peer|client|router), ``$SOFIA_ZENOH_CONNECT`` and
   ``$SOFIA_ZENOH_LISTEN`` (comma-separated endpoints, e.g. ``tcp/zenoh:7447``);
4. command-line flags: ``--zenoh-mode``, ``--connect``, ``--listen``.

When connect endpoints are given (a router, as in compose), multicast scouting is turned off:
discovery goes through the router, and multicast does not cross Docker networks anyway; the
session then waits for the router when it is not reachable yet, rather than failing, and
reconnects by itself after a router restart.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
from dataclasses import dataclass, field
from pathlib import Path

import zenoh

log = logging.getLogger(__name__)
ENV_CONFIG = "SOFIA_ZENOH_CONFIG"
ENV_MODE = "SOFIA_ZENOH_MODE"
ENV_CONNECT = "SOFIA_ZENOH_CONNECT"
ENV_LISTEN = "SOFIA_ZENOH_LISTEN"
DEFAULT_LISTEN = ["tcp/127.0.0.1:0"]
DEFAULT_ROUTER_LISTEN = ["tcp/127.0.0.1:7447"]
MODES = ("peer", "client", "router")
CONNECT_TIMEOUT_MS = {"router": -1, "peer": -1, "client": -1}
EXIT_ON_FAILURE = {"router": False, "peer": False, "client": False}
CONNECT_RETRY = {"period_init_ms": 250, "period_max_ms": 2000, "period_increase_factor": 1.5}


def _split(value: str | None) -> list[str]:
    return [v.strip() for v in value.split(",") if v.strip()] if value else []


@dataclass
class ZenohOptions:
    """Where a session connects and listens. ``None`` means "not set at this level"."""

    mode: str | None = None
    connect: list[str] = field(default_factory=list)
    listen: list[str] = field(default_factory=list)
    config_file: str | None = None

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> ZenohOptions:
        return cls(
            mode=getattr(args, "zenoh_mode", None),
            connect=list(getattr(args, "connect", None) or []),
            listen=list(getattr(args, "listen", None) or []),
            config_file=getattr(args, "zenoh_config", None),
        )


def add_zenoh_args(parser: argparse.ArgumentParser) -> None:
    """Add ``--zenoh-mode``, ``--connect``, ``--listen``, ``--zenoh-config`` to a parser."""
    g = parser.add_argument_group("zenoh")
    g.add_argument("--zenoh-mode", choices=MODES, default=None, help="session mode (default peer)")
    g.add_argument("--connect", action="append", metavar="ENDPOINT", help="e.g. tcp/127.0.0.1:7447")
    g.add_argument("--listen", action="append", metavar="ENDPOINT", help="e.g. tcp/127.0.0.1:0")
    g.add_argument("--zenoh-config", metavar="FILE", help="json5 Zenoh config file")


def _explicit(options: ZenohOptions, env: dict[str, str]) -> dict[str, object]:
    """Settings given by flags (level 4) or, failing that, the environment (level 3)."""
    out: dict[str, object] = {}
    mode = options.mode or env.get(ENV_MODE)
    if mode:
        if mode not in MODES:
            raise ValueError(f"Zenoh mode {mode!r} is not one of {MODES}")
        out["mode"] = mode
    connect = options.connect or _split(env.get(ENV_CONNECT))
    if connect:
        out["connect"] = connect
    listen = options.listen or _split(env.get(ENV_LISTEN))
    if listen:
        out["listen"] = listen
    return out


def resolve(options: ZenohOptions | None = None, env: dict[str, str] | None = None) -> dict[str, object]:
    """The effective settings as a dict: mode, connect, listen, config_file, multicast.

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
        }
        base.update(explicit)
        return {**base, "config_file": config_file}
    mode = str(explicit.get("mode", "peer"))
    connect = explicit.get("connect", [])
    listen = explicit.get("listen", [])
    if not listen and mode != "client":
        listen = DEFAULT_ROUTER_LISTEN if mode == "router" else DEFAULT_LISTEN
    return {
        "mode": mode,
        "connect": connect,
        "listen": listen,
        "config_file": None,
        "multicast": not connect,
    }


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
        return conf
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(s["mode"]))
    if s["connect"]:
        conf.insert_json5("connect/endpoints", json.dumps(s["connect"]))
    if s["listen"]:
        conf.insert_json5("listen/endpoints", json.dumps(s["listen"]))
    if s["multicast"]:
        conf.insert_json5("scouting/multicast/enabled", "true")
        conf.insert_json5("scouting/multicast/interface", json.dumps("lo"))
    else:
        conf.insert_json5("scouting/multicast/enabled", "false")
    if s["connect"]:
        # wait for the router instead of failing when it is not up yet (or restarting), retrying
        # every 0.25 s to 2 s; the same retry brings sessions back after a router restart
        log.info("connecting to %s (waiting until reachable)", s["connect"])
        conf.insert_json5("connect/timeout_ms", json.dumps(CONNECT_TIMEOUT_MS))
        conf.insert_json5("connect/exit_on_failure", json.dumps(EXIT_ON_FAILURE))
        conf.insert_json5("connect/retry", json.dumps(CONNECT_RETRY))
    return conf


def open_session(options: ZenohOptions | None = None) -> zenoh.Session:
    """Open a Zenoh session with :func:`zenoh_config`."""
    return zenoh.open(zenoh_config(options))
