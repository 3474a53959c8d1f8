"""Autonomous calibration in the simulated cell: franky-sim behind the arm service, the simulated
D435 rendering the blob sheet from the live flange pose through a true T_flange_cam of an unusual
rotation, the calibrator service, and ``sofia calibrate auto`` printing the progress."""

from __future__ import annotations

import subprocess
from collections.abc import Callable

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sofia_schemas.transforms import rotation_angle

from ..conftest import SOFIA, Proc
from .test_pick_place import sim_truth


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_sofia_calibrate_auto_finds_a_sideways_camera(sofia_proc: Callable[..., Proc], robot_id: str) -> None:
    q = Rotation.from_rotvec(
        np.radians([10.0, -60.0, 80.0])
    ).as_quat()  # optical axis 60 deg off the flange z
    t_q = " ".join(f"{v:.6f}" for v in [-0.06, 0.02, 0.07, *q])
    truth = sim_truth("--sim-scene", "calibration", "--sim-T-flange-cam", t_q)
    T_true = np.array(truth["T_flange_cam"])
    arm = sofia_proc("arm", "serve", "--sim", "--max-speed", "1.0")
    sofia_proc("camera", "serve", "--sim", "--sim-scene", "calibration", "--sim-T-flange-cam", t_q)
    sofia_proc("calibrator", "serve", "--state-dir", str(arm.log_path.parent / "calibrator"))
    arm.wait_for_log("connected to the robot", 120)
    env = {"SOFIA_ROBOT": robot_id, "PATH": "/usr/bin:/bin"}
    out = subprocess.run([SOFIA, "calibrate", "auto", "--speed", "1.0", "--json"], capture_output=True, text=True,
                         timeout=600, env=env)  # fmt: skip
    import json

    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert out.returncode == 0, (out.stderr, res["reason"], [p["reason"] for p in res["phases"]])
    T_est = np.array(res["details"]["result"]["matrix"])
    err_mm = 1e3 * np.linalg.norm(T_est[:3, 3] - T_true[:3, 3])
    err_deg = float(np.degrees(rotation_angle(T_est[:3, :3].T @ T_true[:3, :3])))
    assert err_mm < 1.0 and err_deg < 0.2, (err_mm, err_deg)
    assert res["details"]["samples"] <= 20
