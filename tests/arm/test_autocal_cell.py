"""Autonomous calibration in the simulated cell: franky-sim behind the arm service, the simulated
D435 rendering the blob sheet from the live flange pose through a true T_flange_cam of an unusual
rotation (or, eye-to-hand, a ball on the flange from a fixed mount), the calibrator service, and
``sofia calibrate auto`` printing the progress."""

from __future__ import annotations

import json
import subprocess
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sofia_schemas.sim_world import read_world

from ..conftest import SOFIA, Proc, gap_mm_deg
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
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert out.returncode == 0, (out.stderr, res["reason"], [p["reason"] for p in res["phases"]])
    T_est = np.array(res["details"]["result"]["matrix"])
    err_mm, err_deg = gap_mm_deg(T_est, T_true)
    assert err_mm < 1.0 and err_deg < 0.2, (err_mm, err_deg)
    assert res["details"]["samples"] <= 20


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.parametrize("radius", [["--ball-radius", "0.025"], []], ids=["radius-given", "radius-fitted"])
def test_sofia_calibrate_auto_eye_to_hand_finds_the_fixed_camera(
    sofia_proc: Callable[..., Proc], robot_id: str, tmp_path: Path, radius: list[str]
) -> None:
    """A fixed simulated camera (mount and ball in the shared world file), a ball on the flange:
    the arm finds the camera, plans views of the ball, the calibrator solves T_base_cam live
    (the ball's radius given, or one radius fitted to all the views)."""
    world = tmp_path / "world.json"
    ball = ["--sim-ball", "0.015", "-0.01", "0.11", "0.025"]
    truth = sim_truth("--sim-scene", "eye-to-hand", *ball)
    T_true = np.array(truth["T_base_cam"])
    env = {"SOFIA_SIM_WORLD": str(world)}
    arm = sofia_proc("arm", "serve", "--sim", "--max-speed", "1.0", env=env)
    sofia_proc("camera", "serve", "--sim", "--sim-scene", "eye-to-hand", *ball, env=env)
    sofia_proc("calibrator", "serve", "--state-dir", str(tmp_path / "calibrator"))
    arm.wait_for_log("connected to the robot", 120)
    assert read_world(world) is not None and read_world(world).flange_ball is not None  # type: ignore[union-attr]
    out = subprocess.run([SOFIA, "calibrate", "auto", "--setup", "eye-to-hand", *radius,
                          "--speed", "1.0", "--json"], capture_output=True, text=True, timeout=600,
                         env={"SOFIA_ROBOT": robot_id, "PATH": "/usr/bin:/bin"})  # fmt: skip
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert out.returncode == 0, (out.stderr, res["reason"], [p["reason"] for p in res["phases"]])
    r = res["details"]["result"]
    T_est = np.array(r["matrix"])
    err_mm, err_deg = gap_mm_deg(T_est, T_true)
    assert err_mm < 1.0 and err_deg < 0.2, (err_mm, err_deg, [p["reason"] for p in res["phases"]])
    assert 1e3 * np.linalg.norm(np.array(r["target_base"]) - [0.015, -0.01, 0.11]) < 1.0
    assert r["parent_frame"] == "panda_link0" and res["details"]["samples"] <= 20


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_sofia_calibrate_auto_with_a_ball_on_the_table(
    sofia_proc: Callable[..., Proc], robot_id: str
) -> None:
    """Eye-in-hand with a coloured ball on the table in place of the blob (the camera service's
    ``ball`` scene), its radius fitted: one radius shared by the views."""
    scene = ["--sim-scene", "ball", "--sim-ball", "0", "0", "0", "0.025"]
    truth = sim_truth(*scene)
    T_true, ball = np.array(truth["T_flange_cam"]), np.array(truth["ball"]["p_base"])
    arm = sofia_proc("arm", "serve", "--sim", "--max-speed", "1.0")
    sofia_proc("camera", "serve", "--sim", *scene)
    sofia_proc("calibrator", "serve", "--state-dir", str(arm.log_path.parent / "calibrator"))
    arm.wait_for_log("connected to the robot", 120)
    out = subprocess.run([SOFIA, "calibrate", "auto", "--target", "ball", "--speed", "1.0", "--json"],
                         capture_output=True, text=True, timeout=600,
                         env={"SOFIA_ROBOT": robot_id, "PATH": "/usr/bin:/bin"})  # fmt: skip
    res = json.loads(out.stdout.strip().splitlines()[-1])
    reasons = [p["reason"] for p in res["phases"]]
    assert out.returncode == 0, (out.stderr, res["reason"], reasons)
    r = res["details"]["result"]
    T_est = np.array(r["matrix"])
    err_mm, err_deg = gap_mm_deg(T_est, T_true)
    assert err_mm < 1.0 and err_deg < 0.2, (err_mm, err_deg, reasons)
    assert 1e3 * np.linalg.norm(np.array(r["target_base"]) - ball) < 1.0
    assert any("shared by" in s for s in reasons) and res["details"]["samples"] <= 20
