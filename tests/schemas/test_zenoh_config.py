"""Zenoh config precedence: defaults < config file < environment < flags."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest
from sofia_schemas.zenoh_config import (
    ZenohOptions,
    add_zenoh_args,
    resolve,
    zenoh_config,
)


def _get(conf: object, key: str) -> object:
    return json.loads(conf.get_json(key))  # type: ignore[attr-defined]


@pytest.fixture
def config_file(tmp_path: Path) -> Path:
    path = tmp_path / "zenoh.json5"
    path.write_text(
        '// a json5 file\n{ mode: "client", connect: { endpoints: ["tcp/10.0.0.1:7447"] },'
        ' listen: { endpoints: ["tcp/127.0.0.1:7555"] } }\n'
    )
    return path


def test_defaults_peer_on_loopback() -> None:
    s = resolve(ZenohOptions(), env={})
    assert s == {
        "mode": "peer",
        "connect": [],
        "listen": ["tcp/127.0.0.1:0"],
        "config_file": None,
        "multicast": True,
    }
    conf = zenoh_config(ZenohOptions(), env={})
    assert _get(conf, "mode") == "peer"
    assert _get(conf, "listen/endpoints") == ["tcp/127.0.0.1:0"]
    assert _get(conf, "scouting/multicast/enabled") is True
    assert _get(conf, "scouting/multicast/interface") == "lo"


def test_router_mode_default_listen() -> None:
    assert resolve(ZenohOptions(mode="router"), env={})["listen"] == ["tcp/127.0.0.1:7447"]


def test_environment_over_defaults() -> None:
    env = {"SOFIA_ZENOH_MODE": "client", "SOFIA_ZENOH_CONNECT": "tcp/zenoh:7447, tcp/other:7447"}
    s = resolve(ZenohOptions(), env=env)
    assert s["mode"] == "client" and s["connect"] == ["tcp/zenoh:7447", "tcp/other:7447"]
    assert s["listen"] == [] and s["multicast"] is False
    conf = zenoh_config(ZenohOptions(), env=env)
    assert _get(conf, "connect/endpoints") == ["tcp/zenoh:7447", "tcp/other:7447"]
    assert _get(conf, "scouting/multicast/enabled") is False


def test_flags_over_environment() -> None:
    env = {
        "SOFIA_ZENOH_MODE": "client",
        "SOFIA_ZENOH_CONNECT": "tcp/zenoh:7447",
        "SOFIA_ZENOH_LISTEN": "tcp/127.0.0.1:1",
    }
    s = resolve(
        ZenohOptions(mode="peer", connect=["tcp/127.0.0.1:9000"], listen=["tcp/127.0.0.1:2"]), env=env
    )
    assert (s["mode"], s["connect"], s["listen"]) == ("peer", ["tcp/127.0.0.1:9000"], ["tcp/127.0.0.1:2"])


def test_file_over_defaults(config_file: Path) -> None:
    conf = zenoh_config(ZenohOptions(config_file=str(config_file)), env={})
    assert _get(conf, "mode") == "client"
    assert _get(conf, "connect/endpoints") == ["tcp/10.0.0.1:7447"]
    assert _get(conf, "listen/endpoints") == ["tcp/127.0.0.1:7555"]
    s = resolve(ZenohOptions(), env={"SOFIA_ZENOH_CONFIG": str(config_file)})
    assert (s["mode"], s["config_file"]) == ("client", str(config_file))


def test_environment_and_flags_over_file(config_file: Path) -> None:
    env = {"SOFIA_ZENOH_CONFIG": str(config_file), "SOFIA_ZENOH_MODE": "peer"}
    conf = zenoh_config(ZenohOptions(listen=["tcp/127.0.0.1:7666"]), env=env)
    assert _get(conf, "mode") == "peer"  # environment
    assert _get(conf, "listen/endpoints") == ["tcp/127.0.0.1:7666"]  # flag
    assert _get(conf, "connect/endpoints") == ["tcp/10.0.0.1:7447"]  # file


def test_flags_from_argparse(config_file: Path) -> None:
    parser = argparse.ArgumentParser()
    add_zenoh_args(parser)
    args = parser.parse_args(
        [
            "--zenoh-mode",
            "client",
            "--connect",
            "tcp/a:1",
            "--connect",
            "tcp/b:2",
            "--zenoh-config",
            str(config_file),
        ]
    )
    opts = ZenohOptions.from_args(args)
    assert opts == ZenohOptions(
        mode="client", connect=["tcp/a:1", "tcp/b:2"], listen=[], config_file=str(config_file)
    )
    assert ZenohOptions.from_args(argparse.Namespace()) == ZenohOptions()


def test_missing_config_file() -> None:
    with pytest.raises(FileNotFoundError, match=r"Zenoh config file '/nonexistent\.json5' does not exist"):
        zenoh_config(ZenohOptions(config_file="/nonexistent.json5"), env={})


def test_invalid_mode() -> None:
    with pytest.raises(ValueError, match="Zenoh mode 'server' is not one of"):
        resolve(ZenohOptions(), env={"SOFIA_ZENOH_MODE": "server"})
