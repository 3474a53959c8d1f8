"""``/tf_static`` (reliable, transient local) sends rmw_zenoh's sample-miss heartbeat: after each
new calibration on the bus, within the heartbeat period, the last sample's sequence number on the
advanced publisher's heartbeat key (a subscriber that lost the last sample queries it from the
cache); none while nothing new is published (sporadic, as rmw_zenoh's)."""

from __future__ import annotations

import struct
import time

import numpy as np
import zenoh
from sofia_runtime.ros2.rmw import SAMPLE_MISS_HEARTBEAT_S, data_key
from sofia_runtime.zenoh_config import ZenohOptions, zenoh_config
from sofia_schemas.keys import ENCODING_JSON, Keys
from sofia_schemas.messages import CalibrationResult
from sofia_schemas.ros2 import convert as cv

from ..conftest import Collector, calibration_result


def _calibration(stamp_ns: int) -> CalibrationResult:
    T_flange_cam = np.array(
        [[0.0, -1.0, 0.0, 0.065], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.045], [0, 0, 0, 1.0]]
    )
    return calibration_result(T_flange_cam, stamp_ns)


def _wait(collector: Collector, n: int, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while len(collector.samples) < n and time.monotonic() < deadline:
        time.sleep(0.02)


def test_tf_static_sends_a_sporadic_sample_miss_heartbeat(bus, sofia_proc, robot_id: str) -> None:  # type: ignore[no-untyped-def]
    bridge = sofia_proc("ros2", "serve", "--no-tf-input", "--camera-topic", "", env=bus.env)
    bridge.wait_for_log("ros2 ready")
    key = data_key(0, "/tf_static", cv.TF_MESSAGE)
    conf = zenoh_config(ZenohOptions(mode="client", connect=[f"tcp/127.0.0.1:{bus.port}"]))
    samples, heartbeats = Collector(), Collector()
    with zenoh.open(conf) as session:
        subs = [
            session.declare_subscriber(key, samples),
            session.declare_subscriber(f"{key}/@adv/pub/**", heartbeats),
        ]
        time.sleep(0.5)  # the subscriptions reach the bridge
        for n in (1, 2):  # two calibrations, more than a heartbeat period apart
            session.put(
                Keys(robot_id).calibration_result, _calibration(n).to_json_bytes(), encoding=ENCODING_JSON
            )
            _wait(samples, n, timeout=10)
            _wait(heartbeats, n, timeout=2 * SAMPLE_MISS_HEARTBEAT_S + 1)
            assert (len(samples.samples), len(heartbeats.samples)) == (n, n), bridge.log()[-1500:]
            time.sleep(SAMPLE_MISS_HEARTBEAT_S + 0.3)
        time.sleep(2 * SAMPLE_MISS_HEARTBEAT_S)  # nothing new published: no heartbeat
        for sub in subs:
            sub.undeclare()
    beats = heartbeats.samples
    assert len(beats) == 2, [b.key for b in beats]
    # each carries the last sample's sequence number (0, then 1), on the publisher's own key
    assert [struct.unpack("<I", b.payload)[0] for b in beats] == [0, 1]
    assert beats[0].key == beats[1].key and beats[0].key.startswith(f"{key}/@adv/pub/")
    # the heartbeat follows its sample within the period
    assert all(
        0 <= b.t - s.t <= SAMPLE_MISS_HEARTBEAT_S + 0.3 for b, s in zip(beats, samples.samples, strict=True)
    )
