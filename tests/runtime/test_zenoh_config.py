"""Zenoh config precedence: defaults < config file < environment < flags."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest
import zenoh
from sofia_runtime.zenoh_config import (
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


def test_defaults_peer_on_local_sockets_only(tmp_path: Path) -> None:
    env = {"SOFIA_ZENOH_SOCKET_DIR": str(tmp_path / "sock")}
    s = resolve(ZenohOptions(), env=env)
    (local,) = s["listen"]  # type: ignore[misc]
    assert local.startswith(f"unixsock-stream/{tmp_path / 'sock'}/")
    assert {k: v for k, v in s.items() if k != "listen"} == {
        "mode": "peer",
        "connect": [],
        "config_file": None,
        "multicast": False,  # no scouting: another user's peer is never heard of
        "protocols": ["unixsock-stream"],
        "local_peers": [],
    }
    assert (tmp_path / "sock").stat().st_mode & 0o777 == 0o700  # other users cannot reach the bus
    conf = zenoh_config(ZenohOptions(), env=env)
    assert _get(conf, "mode") == "peer"
    assert _get(conf, "transport/link/protocols") == ["unixsock-stream"]
    assert _get(conf, "scouting/multicast/enabled") is False
    own = _get(conf, "listen/endpoints")[0]  # type: ignore[index]
    assert own.startswith("unixsock-stream/")  # type: ignore[union-attr]
    with zenoh.open(conf):  # the next session dials this user's earlier ones
        later = zenoh_config(ZenohOptions(), env=env)
    assert own in _get(later, "connect/endpoints")  # type: ignore[operator]
    assert _get(later, "connect/timeout_ms") == {"router": 0, "peer": 0, "client": 0}


def test_each_session_its_own_socket_and_stale_ones_pruned(tmp_path: Path) -> None:
    env = {"SOFIA_ZENOH_SOCKET_DIR": str(tmp_path)}
    stale = tmp_path / "999999999-deadbeef.sock"  # a pid that cannot exist
    stale.touch()
    a, b = (resolve(ZenohOptions(), env=env)["listen"] for _ in range(2))
    assert a != b
    assert not stale.exists()


def test_router_mode_default_listen(tmp_path: Path) -> None:
    s = resolve(ZenohOptions(mode="router"), env={"SOFIA_ZENOH_SOCKET_DIR": str(tmp_path)})
    (local,) = s["listen"]  # type: ignore[misc]
    assert local.startswith(f"unixsock-stream/{tmp_path}/")  # no TCP unless asked
    assert s["protocols"] == ["unixsock-stream"]
    s = resolve(ZenohOptions(mode="router", listen=["local", "tcp/127.0.0.1:7447"]),
                env={"SOFIA_ZENOH_SOCKET_DIR": str(tmp_path)})  # fmt: skip
    assert s["listen"][0] == "tcp/127.0.0.1:7447" and s["protocols"] == ["unixsock-stream", "tcp"]  # type: ignore[index]
    conf = zenoh_config(ZenohOptions(mode="router"), env={"SOFIA_ZENOH_SOCKET_DIR": str(tmp_path)})
    assert _get(conf, "scouting/multicast/enabled") is False


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


@pytest.mark.parametrize("source", ["file", "file+environment", "environment"])
def test_wait_for_router_whatever_the_config_source(config_file: Path, source: str) -> None:
    env = {"SOFIA_ZENOH_CONNECT": "tcp/127.0.0.1:9"} if "environment" in source else {}
    if "file" in source:
        env["SOFIA_ZENOH_CONFIG"] = str(config_file)
    conf = zenoh_config(ZenohOptions(), env=env)
    assert _get(conf, "connect/timeout_ms") == {"router": -1, "peer": -1, "client": -1}
    assert _get(conf, "connect/exit_on_failure") == {"router": False, "peer": False, "client": False}
    assert _get(conf, "connect/retry")["period_max_ms"] == 2000  # type: ignore[index]


def test_a_file_keeps_its_own_connect_timeout(tmp_path: Path) -> None:
    path = tmp_path / "z.json5"
    path.write_text('{ mode: "client", connect: { endpoints: ["tcp/127.0.0.1:9"], timeout_ms: 5000 } }')
    conf = zenoh_config(ZenohOptions(config_file=str(path)), env={})
    assert _get(conf, "connect/timeout_ms") == 5000
    assert _get(conf, "connect/exit_on_failure") == {"router": False, "peer": False, "client": False}


def test_user_and_password_file_from_the_environment(config_file: Path, tmp_path: Path) -> None:
    (tmp_path / "pw").write_text("s3cret\n")
    env = {"SOFIA_ZENOH_CONFIG": str(config_file), "SOFIA_ZENOH_USER": "calibrator",
           "SOFIA_ZENOH_PASSWORD_FILE": str(tmp_path / "pw")}  # fmt: skip
    usrpwd = _get(zenoh_config(ZenohOptions(), env=env), "transport/auth/usrpwd")
    assert usrpwd["user"] == "calibrator" and usrpwd["password"] == "s3cret"  # type: ignore[index]
    env["SOFIA_ZENOH_PASSWORD_FILE"] = str(tmp_path / "missing")
    with pytest.raises(FileNotFoundError, match=r"SOFIA_ZENOH_USER is set but \$SOFIA_ZENOH_PASSWORD_FILE"):
        zenoh_config(ZenohOptions(), env=env)
