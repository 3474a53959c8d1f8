"""The ROS 2 bridge closes cleanly while it is still asking for the calibrator's last result."""

from __future__ import annotations

import threading
import time
import uuid

import zenoh
from sofia_runtime import zenoh_config
from sofia_runtime.ros2.bridge import Bridge, BridgeConfig
from sofia_schemas.keys import Keys


def test_the_bridge_closes_while_the_calibrators_answer_is_on_its_way() -> None:
    """A calibrator that takes 1.5 s to answer: the bridge's background fetch is waiting on the
    session when the bridge closes. Closing joins it first (it was left running before), so no
    thread of the bridge uses the session once it closes (a session cannot close while another
    thread is inside one of its calls: "Already borrowed", the session stays open and the process
    aborts as it exits). The late answer goes through the same conversion as the subscriber's."""
    robot = f"t{uuid.uuid4().hex[:8]}"
    calibrator = zenoh.open(zenoh_config())

    def slow(query: zenoh.Query) -> None:
        time.sleep(1.5)
        query.reply(query.key_expr, b"{}")

    queryable = calibrator.declare_queryable(Keys(robot).calibration_result, slow)
    conf = zenoh_config()
    conf.insert_json5("timestamping/enabled", "true")  # as the bridge's service opens it
    session = zenoh.open(conf)
    try:
        time.sleep(0.5)  # the sessions find each other
        before = set(threading.enumerate())
        bridge = Bridge(session, BridgeConfig(robot=robot, camera_topic="", tf_input=False))
        time.sleep(0.3)  # the fetch is waiting for the answer
        bridge.close()
        left = [t for t in threading.enumerate() if t not in before and "pyo3" not in t.name]
        assert not left, "the bridge's threads left running"  # (zenoh's own callback threads aside)
        session.close()
        assert session.is_closed()
        assert bridge.counters["errors"] == 1, "the empty answer is reported as not a result"
    finally:
        queryable.undeclare()
        calibrator.close()
