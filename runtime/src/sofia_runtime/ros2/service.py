"""``sofia ros2 serve``: SofIA's topics and services on the ROS 2 graph (rmw_zenoh), ROS 2 inputs in.

Its status (``Keys(robot).status("ros2")``) counts samples sent out, taken in, service requests and
errors.

On SofIA's local bus (peer mode) the bridge also listens on a loopback TCP port
(:data:`ROS2_PEER_LISTEN`) and may dial TCP: rmw_zenoh nodes learn each other through the router's
gossip and the peer with the greater Zenoh id dials the other (``to_peer: "greater-zid"``); data
then flows peer to peer. With Unix sockets only, a node with the smaller id was never dialled and got
neither the bridge's liveliness tokens nor its data.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, replace
from typing import cast

import zenoh
from sofia_schemas.keys import Keys
from sofia_schemas.messages import ServiceStatus, now_ns

from ..service import StatusEndpoint, StopFlag, serve
from ..zenoh_config import LOCAL_PROTOCOL, ZenohOptions, resolve, socket_dir, zenoh_config
from .bridge import Bridge, BridgeConfig

log = logging.getLogger("sofia.ros2")
ROS2_PEER_LISTEN = "tcp/127.0.0.1:0"  # loopback only: the same local users who reach the --ros2 router


@dataclass
class ServiceConfig:
    bridge: BridgeConfig
    zenoh: ZenohOptions


def bridge_options(options: ZenohOptions, env: dict[str, str] | None = None) -> ZenohOptions:
    """``options`` plus a :data:`ROS2_PEER_LISTEN` listener when the session is a peer of the local
    bus without TCP listeners of its own; unchanged with a config file, in client mode or when a TCP
    listener is given (``--listen``, ``$SOFIA_ZENOH_LISTEN``)."""
    env = dict(os.environ if env is None else env)
    settings = resolve(options, env)
    listen = cast(list[str], settings["listen"])
    if settings["config_file"] or settings["mode"] != "peer" or any(e.startswith("tcp/") for e in listen):
        return options
    own_sockets = f"{LOCAL_PROTOCOL}/{socket_dir(env)}/"
    given = [e for e in listen if not e.startswith(own_sockets)]
    return replace(options, listen=[*given, ROS2_PEER_LISTEN])


def main(config: ServiceConfig) -> int:
    """Run until SIGINT/SIGTERM."""
    stop = StopFlag()
    keys = Keys(config.bridge.robot)
    conf = zenoh_config(bridge_options(config.zenoh))
    conf.insert_json5("timestamping/enabled", "true")  # /tf_static's cache (as rmw_zenoh's sessions)
    with zenoh.open(conf) as session:
        bridge = Bridge(session, config.bridge)

        def status() -> ServiceStatus:
            return ServiceStatus(
                service="ros2", stamp_ns=now_ns(), state="ok", detail=bridge.last_error,
                counters=dict(bridge.counters),
                info={"domain": bridge.graph.domain, "zid": bridge.graph.zid,
                      "detect_object": bridge.detect_service},
            )  # fmt: skip

        endpoint = StatusEndpoint(session, keys.status("ros2"), status)
        log.info(
            "ros2 ready: domain %d, nodes %s, detect_object on %s, camera in %r, /tf in %s",
            bridge.graph.domain, [n.name for n in bridge.nodes], bridge.detect_service,
            config.bridge.camera_topic, config.bridge.tf_input,
        )  # fmt: skip
        code = serve(stop, endpoint, [], name="ros2", log=log)
        bridge.close()
    return code
