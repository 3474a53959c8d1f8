"""The bridge's session on SofIA's local bus is dialable by rmw_zenoh peers over loopback TCP (they
dial by the greater Zenoh id); elsewhere its Zenoh settings are left as given."""

from __future__ import annotations

from pathlib import Path

from sofia_runtime.ros2.service import ROS2_PEER_LISTEN, bridge_options
from sofia_runtime.zenoh_config import LOCAL_PROTOCOL, ZenohOptions, resolve


def _env(tmp_path: Path, **extra: str) -> dict[str, str]:
    return {"SOFIA_ZENOH_SOCKET_DIR": str(tmp_path / "sockets"), **extra}


def test_local_peer_bridge_listens_on_loopback_tcp_and_its_socket(tmp_path: Path) -> None:
    env = _env(tmp_path)
    settings = resolve(bridge_options(ZenohOptions(), env), env)
    assert settings["mode"] == "peer"
    listen = settings["listen"]
    assert isinstance(listen, list) and ROS2_PEER_LISTEN in listen
    assert [e for e in listen if e.startswith(f"{LOCAL_PROTOCOL}/{tmp_path / 'sockets'}/")]  # the user's bus
    assert settings["protocols"] == [LOCAL_PROTOCOL, "tcp"]  # dials rmw_zenoh nodes' TCP listeners


def test_listen_endpoints_from_the_environment_are_kept(tmp_path: Path) -> None:
    env = _env(tmp_path, SOFIA_ZENOH_LISTEN="udp/127.0.0.1:0")
    listen = bridge_options(ZenohOptions(), env).listen
    assert listen == ["udp/127.0.0.1:0", ROS2_PEER_LISTEN]


def test_given_tcp_listener_client_mode_and_config_file_are_left_alone(tmp_path: Path) -> None:
    env = _env(tmp_path)
    given = ZenohOptions(listen=["tcp/127.0.0.1:7500"])
    assert bridge_options(given, env) == given
    client = ZenohOptions(mode="client", connect=["tcp/127.0.0.1:7447"])
    assert bridge_options(client, env) == client
    conf = tmp_path / "zenoh.json5"
    conf.write_text('{mode: "peer"}')
    from_file = ZenohOptions(config_file=str(conf))
    assert bridge_options(from_file, env) == from_file
