"""The steps of ``sofia demo``: each talks to the running services and adds a line to the summary."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import numpy as np
import zenoh
from sofia_replay.mcap_io import read_truth
from sofia_runtime.client import QueryError, ask, query
from sofia_schemas import Keys
from sofia_schemas.keys import TOPIC_BLOB, TOPIC_CAMERA_POINTS, TOPIC_FLANGE_POSE, TOPIC_POINTS
from sofia_schemas.messages import CalibrationResult, Detection, GripperCommand, GripperResult, PickTarget
from sofia_schemas.transforms import rotation_angle

from .bus import Collector, wait_until
from .launcher import sofia_executable
from .summary import Summary, say
from .wording import describe_detection, transform_text

OBJECT_WIDTH_MM = 40.0  # the object between the emulated fingers


def sofia(*args: str, env_robot: str, timeout: float = 300.0) -> subprocess.CompletedProcess[str]:
    """Run ``sofia ARGS`` for robot ``env_robot`` and capture its output."""
    env = dict(os.environ, SOFIA_ROBOT=env_robot)
    return subprocess.run(
        [*sofia_executable(), *args], capture_output=True, text=True, timeout=timeout, env=env
    )


def _truth_frames(scenes_mcap: Path) -> dict[int, dict]:
    """The recording's true scenes by stamp (ns)."""
    truth = read_truth(scenes_mcap) or {}
    return {int(f["stamp_ns"]): f for f in truth.get("frames", [])}


def _replay_and_check(session: zenoh.Session, keys: Keys, scenes_mcap: Path, robot: str, topics: list[str],
                      step: str, summary: Summary) -> bool:  # fmt: skip
    """Replay ``topics`` of the scene recording and print each detection against the truth."""
    frames = _truth_frames(scenes_mcap)
    order = {stamp: i for i, stamp in enumerate(sorted(frames))}
    t0_ns = min(frames, default=0)
    errors: list[float] = []
    transforms: list[str] = []

    def show(det: Detection) -> None:
        frame = frames.get(det.stamp_ns)
        text, err = describe_detection(det, frame["objects"] if frame else None)
        if err is not None:
            errors.append(err)
        if det.transform and det.transform not in transforms:  # said once, when it changes
            transforms.append(det.transform)
            say(f"  (camera clouds mapped into the base frame with {transform_text(det.transform)})")
        scene = f"scene {order[det.stamp_ns] + 1}/{len(frames)}" if frame else "a cloud"
        say(f"  {scene} at {(det.stamp_ns - t0_ns) / 1e9:.1f} s: {text}")

    dets = Collector(session, keys.detections, Detection, show)
    say(f"replaying {', '.join(topics)} of {scenes_mcap} ...")
    args = [a for t in topics for a in ("--topic", t)]
    played = sofia(
        "replay",
        "play",
        "--wait-subscribers",
        "10",
        str(scenes_mcap),
        *args,
        "--robot",
        robot,
        env_robot=robot,
    )
    wait_until(lambda: len(dets) >= len(frames), 10)
    dets.close()
    worst = max(errors, default=float("nan"))
    ok = played.returncode == 0 and len(dets) >= len(frames) and bool(errors) and worst < 10
    mean = float(np.mean(errors)) if errors else float("nan")
    summary.add(
        step,
        f"{len(dets)} detections for {len(frames)} clouds; centres {mean:.1f} mm from the truth on average, "
        f"{worst:.1f} mm at most",
        ok,
    )
    if played.returncode != 0:
        say(played.stderr[-2000:])
    return ok


def detections(session: zenoh.Session, keys: Keys, scenes_mcap: Path, robot: str, summary: Summary) -> None:
    """Base-frame clouds (the lab's /pc_glob) -> detections, pick targets and a detect query."""
    picks = Collector(session, keys.pick_target, PickTarget)
    _replay_and_check(session, keys, scenes_mcap, robot, [TOPIC_POINTS], "replay -> detector", summary)
    picks.close()
    frames = _truth_frames(scenes_mcap)
    n_red = sum(any(o["allowed"] for o in f["objects"]) for f in frames.values())
    summary.add("pick targets", f"{len(picks)} published on {keys.pick_target}, for {n_red} clouds with an "
                "object on a red field", len(picks) > 0)  # fmt: skip
    try:
        det = ask(session, keys.detect, Detection)
        frame = frames.get(det.stamp_ns)
        text, err = describe_detection(det, frame["objects"] if frame else None)
        summary.add("detect query (latest cloud)", text, err is None or err < 10)
    except QueryError as e:
        summary.add("detect query (latest cloud)", str(e), False)


def calibration(session: zenoh.Session, keys: Keys, calib_mcap: Path, robot: str, summary: Summary) -> bool:
    truth = read_truth(calib_mcap) or {}
    results = Collector(session, keys.calibration_result, CalibrationResult)
    reset_ok = any(r.ok is not None for r in query(session, keys.calibrator_op("reset"), timeout=5))
    if not reset_ok:
        summary.add("calibrator reset", f"no reply on {keys.calibrator_op('reset')}", False)
    say(f"replaying {calib_mcap} (blob observations + flange poses) into the calibrator ...")
    played = sofia("replay", "play", "--wait-subscribers", "10", str(calib_mcap), "--rate", "4", "--robot", robot,
                    "--topic", TOPIC_BLOB, "--topic", TOPIC_FLANGE_POSE, env_robot=robot)  # fmt: skip
    wait_until(
        lambda: len(results) > 0 and results.items[-1].n_samples >= len(truth.get("frames", [])) - 1, 15
    )
    results.close()
    try:
        res = ask(session, keys.calibrator_op("result"), CalibrationResult)
    except QueryError as e:
        summary.add("calibration", f"{e} (replay exit {played.returncode}: {played.stderr[-500:]})", False)
        return False
    T_est, T_true = np.array(res.matrix), np.array(truth["T_flange_cam"])
    dt_mm = float(np.linalg.norm(T_est[:3, 3] - T_true[:3, 3]) * 1000)
    dr_deg = float(np.degrees(rotation_angle(T_est[:3, :3].T @ T_true[:3, :3])))
    say("T_flange_cam (camera optical frame -> flange, metres):")
    say(np.array2string(T_est, precision=4, suppress_small=True))
    say(
        f"  translation {np.round(res.translation, 4).tolist()} m, quaternion x y z w {np.round(res.quaternion_xyzw, 4).tolist()}"
    )
    say(f"  true translation {np.round(T_true[:3, 3], 4).tolist()} m (the recording's ground truth)")
    say(f"  {res.camera_correction.describe()}")
    say(
        f"  spread per axis {np.round(res.spread_mm, 2).tolist()} mm ({'passes' if res.passes else 'fails'} the 1 cm criterion)"
    )
    if res.ros1_static_transform:
        say(f"  ROS 1: {res.ros1_static_transform}")
    ok = dt_mm < 3.0 and dr_deg < 0.5 and res.passes
    summary.add(
        "calibration vs truth",
        f"{res.n_samples} samples; {dt_mm:.2f} mm / {dr_deg:.3f} deg from the true T_flange_cam",
        ok,
    )
    return ok


def camera_frame(session: zenoh.Session, keys: Keys, scenes_mcap: Path, robot: str, summary: Summary) -> None:
    """Camera-frame clouds + flange poses, mapped to the base frame with the calibrated transform."""
    topics = [TOPIC_CAMERA_POINTS, TOPIC_FLANGE_POSE]
    _replay_and_check(session, keys, scenes_mcap, robot, topics, "camera frame -> base frame", summary)


def gripper(session: zenoh.Session, keys: Keys, summary: Summary) -> None:
    steps = [
        GripperCommand(action="open"),
        GripperCommand(action="grasp", force_n=10.0),
        GripperCommand(action="release"),
    ]
    for cmd in steps:
        try:
            res = ask(
                session, keys.gripper_command, GripperResult, cmd.model_dump_json(), timeout=cmd.timeout_s + 5
            )
            opening = f"{res.opening_mm:.1f} mm" if res.opening_mm is not None else "unknown"
            ok = res.ok
            text = f"{res.reason}, fingers {opening} apart after {res.duration_s:.2f} s"
            if cmd.action == "grasp":  # the emulated object must stop the fingers at its width
                ok = ok and bool(res.grasped) and abs((res.opening_mm or 0.0) - OBJECT_WIDTH_MM) < 3.0
                held = "object held" if res.grasped else "NOTHING held"
                text = f"{held}: fingers stopped at {opening} on the {OBJECT_WIDTH_MM:.0f} mm object, {res.duration_s:.2f} s"
            summary.add(f"gripper {cmd.action}", text, ok)
        except QueryError as e:
            summary.add(f"gripper {cmd.action}", str(e), False)


def plots(scenes_mcap: Path, calib_mcap: Path, out: Path, robot: str, summary: Summary) -> None:
    det_png, dis_png = out / "detection.png", out / "dissipation.png"
    for old in out.glob("detection*.png"):
        old.unlink()
    r = sofia("detect", str(scenes_mcap), "--plot", str(det_png), env_robot=robot)
    plots = sorted(out.glob("detection*.png"))  # one per cloud: detection-<index>.png
    ok = r.returncode == 0 and len(plots) > 0
    summary.add("detection plots", f"{len(plots)} in {out}/detection-*.png" if ok else r.stderr[-300:], ok)
    r = sofia("calibrate", "--mcap", str(calib_mcap), "--plot", str(dis_png), env_robot=robot)
    ok = r.returncode == 0 and dis_png.exists()
    summary.add("dissipation plot", str(dis_png) if ok else r.stderr[-300:], ok)
