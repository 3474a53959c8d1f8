"""Autonomous calibration: poses needed to reach a 1 mm translation 1-sigma, planned (greedy on the
calibrator's covariance) against a fixed 12-pose pattern, and the time of a full calibration.

Both run in the same in-process cell (``sofia_arm.autocal_sim``: a kinematic Panda, the blob sheet
rendered by the simulated D435 through a true T_flange_cam, the calibrator library, the same blob
extraction). The fixed pattern is aimed with the TRUE T_flange_cam (it cannot miss the blob); the
planner starts from nothing (the table gives the camera's rotation, the blob is found from the
start pose). 1-sigma = the calibrator's reported one, never below the noise model's prediction.
Also the coverage of the 1-sigma reported at the planner's stop, over every trial's three flange
axes: the calibrator's translation one alone, the stop rule's, and the calibrator's rotation one.

.venv/bin/python bench/bench_autocal.py [--trials 24]
"""

from __future__ import annotations

import argparse
import logging
import time

import numpy as np
from scipy.spatial.transform import Rotation
from sofia_arm import plan
from sofia_arm.autocal import Autocal, AutocalOptions
from sofia_arm.autocal_io import LocalCalibrator, Progress
from sofia_arm.autocal_sim import KinematicArm, SheetEye
from sofia_arm.poses import solve_ik, views_of
from sofia_calibrator.blob import find_blob
from sofia_calibrator.errors import CalibrationError
from sofia_calibrator.fitting.diagnostics import error6
from sofia_schemas.transforms import invert, pose_gap

BLOB = np.array([0.5, 0.05, 0.0005])
TARGET_MM = 1.0


def error(T_est: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    dt, dr = pose_gap(T_est, T_true)
    return 1e3 * dt, float(np.degrees(dr))


def camera_mount(rng: np.random.Generator) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-0.08, 0.08, 3)
    return T


def fixed_pattern(T_fc: np.ndarray) -> np.ndarray:
    """(12, 4, 4) flange poses of the fixed pattern: 4 azimuths x tilts 20 / 35 deg at 0.4 / 0.5 m,
    4 from above at 0.35-0.6 m, the blob moved around the image as a person would."""
    offsets = np.array([[0.0, 0.0], [8.0, 0.0], [0.0, 6.0], [-8.0, 0.0], [0.0, -6.0]])
    T = [views_of(BLOB, np.array([tilt]), np.array([0.0, 90.0, 180.0, 270.0]), np.array([d]), np.array([0.0]))
         for tilt, d in ((20.0, 0.4), (35.0, 0.5))]  # fmt: skip
    above = views_of(
        BLOB, np.array([0.0]), np.array([0.0]), np.array([0.35, 0.45, 0.55, 0.6]), np.array([0.0])
    )
    T_bc = np.concatenate([*T, above])
    for i in range(len(T_bc)):  # the image offsets, applied as views_of does
        a, b = np.radians(offsets[i % len(offsets)])
        T_bc[i, :3, :3] = T_bc[i, :3, :3] @ Rotation.from_euler("yx", [-a, b]).as_matrix()
    return T_bc @ invert(T_fc)


def run_fixed(T_fc: np.ndarray, seed: int) -> tuple[int | None, int, tuple[float, float]]:
    """(poses needed to reach the target or None, samples taken, final error) of the pattern."""
    arm = KinematicArm()
    eye, cal = SheetEye(arm, T_fc, BLOB, seed), LocalCalibrator()
    needed, n, res = None, 0, None
    for T in fixed_pattern(T_fc):
        ik = solve_ik(T, arm.q(), arm.reach)
        if not ik.ok or not arm.move_joints(ik.q, 1.0).ok:
            continue
        frame = eye.frame_after(arm.clock_ns, 1.0)
        assert frame is not None and frame.rgb is not None
        try:
            blob = find_blob(frame.points_cam, frame.rgb)
        except CalibrationError:
            continue
        cal.add(frame.stamp_ns, blob.p_cam, arm.T_base_flange(), blob.confidence)
        n += 1
        if n >= 3:
            try:
                res = cal.solve()
            except Exception:
                continue
            T_est = np.array(res.matrix)
            info = plan.information(np.array(cal.T_base_flange), T_est, np.array(res.target_base)).sum(0)
            model = plan.translation_sigma_mm(info + 1e-9 * np.eye(9))
            sigma = np.maximum(np.array(res.std_translation_mm), model).max()
            if needed is None and n >= 6 and sigma < TARGET_MM:
                needed = n
    assert res is not None
    return needed, n, error(np.array(res.matrix), T_fc)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=24)
    args = ap.parse_args()
    logging.basicConfig(level=logging.WARNING)
    rng = np.random.default_rng(7)
    rows, planned, fixed, times = [], [], [], []
    z_cal, z_stop, z_rot = [], [], []  # per trial: (3,) |error| / 1-sigma, per flange axis
    for trial in range(args.trials):
        T_fc = camera_mount(rng)
        arm = KinematicArm()
        eye = SheetEye(arm, T_fc, BLOB, seed=trial)
        t0 = time.perf_counter()
        run = Autocal(
            arm, eye, LocalCalibrator(), AutocalOptions(target_sigma_mm=TARGET_MM), Progress(None, None)
        )
        try:
            out = run.run()
            err = error(np.array(out.result.matrix), T_fc) if out.result else (np.nan, np.nan)
            n_plan, visits = out.poses, arm.moves
            if out.result is not None:
                e6 = error6(np.array(out.result.matrix), T_fc)  # flange axes: m, then rad
                z_cal.append(1e3 * np.abs(e6[:3]) / np.array(out.result.std_translation_mm))
                z_stop.append(1e3 * np.abs(e6[:3]) / run.sigma_mm())
                z_rot.append(np.degrees(np.abs(e6[3:])) / np.array(out.result.std_rotation_deg))
        except Exception as e:  # report, keep benchmarking
            n_plan, visits, err = -1, arm.moves, (np.nan, np.nan)
            print(f"trial {trial}: planner failed: {e}")
        times.append(time.perf_counter() - t0)
        needed, n_fixed, err_fixed = run_fixed(T_fc, trial)
        planned.append(n_plan)
        fixed.append(needed if needed is not None else np.nan)
        rows.append(
            (trial, np.round(T_fc[:3, 2], 2).tolist(), n_plan, visits, err, needed, n_fixed, err_fixed)
        )
    print(f"Autonomous calibration, {args.trials} camera mounts of random rotation (offset up to 8 cm), "
          f"target {TARGET_MM} mm translation 1-sigma\n")  # fmt: skip
    for name, z in (
        ("the calibrator's translation", z_cal), ("the stop rule's translation (never below the noise model's)", z_stop),
        ("the calibrator's rotation", z_rot),
    ):  # fmt: skip
        zs = np.concatenate(z) if z else np.zeros(0)
        print(f"coverage of {name} 1-sigma at the stop: {np.mean(zs <= 1):.0%} of {zs.size} axes "
              f"within 1-sigma, {np.mean(zs <= 2):.0%} within 2-sigma (Gaussian: 68 % / 95 %); median "
              f"|error| / 1-sigma {np.median(zs) if zs.size else np.nan:.2f} (Gaussian: 0.67)")  # fmt: skip
    print(
        "| trial | camera axis in flange | planned: samples (moves incl. orient/search) | planned error mm / deg "
        "| fixed 12: samples to target | fixed: samples taken | fixed error after all mm / deg |"
    )
    print("|---|---|---:|---:|---:|---:|---:|")
    for t, axis, n, v, e, need, nf, ef in rows:
        print(f"| {t} | {axis} | {n} ({v}) | {e[0]:.2f} / {e[1]:.3f} | {need if need else 'not reached'} | {nf} "
              f"| {ef[0]:.2f} / {ef[1]:.3f} |")  # fmt: skip
    ok_p = [p for p in planned if p > 0]
    ok_f = [f for f in fixed if np.isfinite(f)]
    mean_p = float(np.mean(ok_p)) if ok_p else np.nan
    mean_f = float(np.mean(ok_f)) if ok_f else np.nan
    print(f"\nsamples to reach {TARGET_MM} mm: planned {mean_p:.1f} (all {len(ok_p)}/{len(planned)} reached), fixed "
          f"pattern {mean_f:.1f} ({len(ok_f)}/{len(fixed)} reached within its 12); ratio planned/fixed "
          f"{mean_p / mean_f:.2f}")  # fmt: skip
    print(
        f"time of a full autonomous calibration in the in-process cell (orient, find, views, solves): "
        f"median {np.median(times):.1f} s (moves take no time here; in franky-sim each move adds 3-10 s)"
    )
    return 0 if len(ok_p) == len(planned) else 1


if __name__ == "__main__":
    raise SystemExit(main())
