"""``sofia ros2 serve``: SofIA's topics and services on the ROS 2 graph (rmw_zenoh), ROS 2 inputs in.

Its status (``Keys(robot).status("ros2")``) counts samples sent out, taken in, service requests and
errors.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import zenoh
from sofia_schemas.keys import Keys
from sofia_schemas.messages import ServiceStatus, now_ns

from ..service import StatusEndpoint, StopFlag
from ..zenoh_config import ZenohOptions, zenoh_config
from .bridge import Bridge, BridgeConfig

log = logging.getLogger("sofia.ros2")
STATUS_PERIOD_S = 1.0


@dataclass
class ServiceConfig:
    bridge: BridgeConfig
    zenoh: ZenohOptions


def main(config: ServiceConfig) -> int:
    """Run until SIGINT/SIGTERM."""
    stop = StopFlag()
    keys = Keys(config.bridge.robot)
    conf = zenoh_config(config.zenoh)
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
        while not stop.wait(STATUS_PERIOD_S):
            endpoint.publish()
        log.info("ros2 stopping")
        endpoint.undeclare()
        bridge.close()
    return 0
