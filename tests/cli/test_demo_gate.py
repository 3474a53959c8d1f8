"""The demo's and the cell's health gate lets through a detector that is degraded only because no
calibration maps its camera-frame clouds yet (by design), and nothing in error."""

from __future__ import annotations

import time
import uuid
from pathlib import Path

import numpy as np
import zenoh
from sofia_runtime.zenoh_config import zenoh_config
from sofia_schemas import pointcloud
from sofia_schemas.frames import CAMERA_FRAME
from sofia_schemas.keys import ENCODING_CDR_POINTCLOUD2, Keys
from sofia_system.launcher import Launcher, ServiceSpec, all_ready


def test_gate_accepts_the_uncalibrated_detector(tmp_path: Path) -> None:
    robot = f"g{uuid.uuid4().hex[:8]}"
    launcher = Launcher([ServiceSpec("detector", ["detector", "serve"], "detector")], tmp_path / "log", robot)
    launcher.start()
    try:
        with zenoh.open(zenoh_config()) as session:
            cloud = pointcloud.encode_points(
                np.array([[0.0, 0.0, 0.5]] * 50), stamp_ns=1, frame_id=CAMERA_FRAME
            )
            deadline = time.monotonic() + 90
            states: dict[str, str] = {}
            while time.monotonic() < deadline:
                launcher.poll()
                states = launcher.check_health(session)
                if states["detector"] == "degraded":
                    break
                if states["detector"] == "ok":  # serving: a camera-frame cloud it cannot map degrades it
                    session.put(Keys(robot).camera_points, bytes(cloud), encoding=ENCODING_CDR_POINTCLOUD2)
                time.sleep(0.3)
            assert states == {"detector": "degraded"}, (states, launcher.last_line("detector"))
            assert all_ready(states)
    finally:
        launcher.stop()
    assert not all_ready({"detector": "error"}) and not all_ready({"gripper": "degraded"})
    assert all_ready({"router": "running", "calibrator": "ok", "detector": "ok"})
