"""The steps of ``sofia demo``: each talks to the running services and adds a line to the summary."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import numpy as np
import zenoh
from sofia_schemas import Keys
from sofia_schemas.client import QueryError, ask, query
from sofia_schemas.keys import TOPIC_BLOB, TOPIC_CAMERA_POINTS, TOPIC_FLANGE_POSE, TOPIC_POINTS
from sofia_schemas.launcher import sofia_executable
from sofia_schemas.messages import CalibrationResult, Detection, GripperCommand, GripperResult, PickTarget
from sofia_schemas.transforms import rotation_angle

from ..mcap_io import read_truth
from .bus import Collector, wait_until
from .summary import Summary, say

OBJECT_WIDTH_MM = 40.0  # the object between the emulated fingers


def sofia(*args: str, env_robot: str, timeout: float = 300.0) -> subprocess.CompletedProcess[str]:
    """Run ``sofia ARGS`` for robot ``env_robot`` and capture its output."""
    env = dict(os.environ, SOFIA_ROBOT=env_robot)
    return subprocess.run(
        [*sofia_executable(), *args], capture_output=True, text=True, timeout=timeout, env=env
    )


def _match_error_mm(det: Detection, truth_frames: dict[int, dict]) -> tuple[str, float | None]:
    frame = truth_frames.get(det.stamp_ns)
    if frame is None:
        return "no truth for this stamp", None
    truths = [np.array(o["center"]) for o in frame["objects"]]
    if not det.objects:
        return ("empty board: no object" if not truths else "MISSED the object"), (
            None if not truths else np.inf
        )
    o = det.objects[0]
    text = f"{len(det.objects)} object(s); first on field {o.field} {'red' if o.allowed else 'NOT red'}"
    if not truths:
        return text + " (but the board is empty!)", np.inf
    err = min(float(np.linalg.norm(np.array(o.center) - t)) for t in truths) * 1000
    return (
        f"{text}, centre ({o.center[0]:.3f}, {o.center[1]:.3f}, {o.center[2]:.3f}) m, error {err:.1f} mm",
        err,
    )


def _replay_and_check(session: zenoh.Session, keys: Keys, scenes_mcap: Path, robot: str, topics: list[str],
                      step: str, summary: Summary) -> bool:  # fmt: skip
    """Replay ``topics`` of the scene recording and print each detection against the truth."""
    truth = read_truth(scenes_mcap) or {}
    frames = {int(f["stamp_ns"]): f for f in truth.get("frames", [])}
    errors: list[float] = []

    def show(det: Detection) -> None:
        text, err = _match_error_mm(det, frames)
        if err is not None:
            errors.append(err)
        used = f" [{det.transform}]" if det.transform else ""
        say(f"  detection @ {det.stamp_ns}: {text}{used}")

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
        f"{len(dets)} detections for {len(frames)} frames, centre error max {worst:.1f} mm, mean {mean:.1f} mm",
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
    summary.add("pick targets", f"{len(picks)} published on {keys.pick_target}", len(picks) > 0)
    try:
        det = ask(session, keys.detect, Detection)
        first = det.objects[0].center if det.objects else None
        summary.add("detect query (latest cloud)", f"status {det.status}, first object centre {first}", True)
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
    say(f"  truth       {np.round(T_true[:3, 3], 4).tolist()} m")
    say(f"  {res.camera_correction.describe()}")
    say(
        f"  spread per axis {np.round(res.spread_mm, 2).tolist()} mm ({'passes' if res.passes else 'fails'} the 1 cm criterion)"
    )
    if res.ros1_static_transform:
        say(f"  ROS 1: {res.ros1_static_transform}")
    ok = dt_mm < 3.0 and dr_deg < 0.5 and res.passes
    summary.add(
        "calibration vs truth", f"{res.n_samples} samples, error {dt_mm:.2f} mm / {dr_deg:.3f} deg", ok
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
            extra = f", grasped {res.grasped}" if res.grasped is not None else ""
            opening = f"{res.opening_mm:.1f} mm" if res.opening_mm is not None else "?"
            ok = res.ok
            if cmd.action == "grasp":  # the emulated object must stop the fingers at its width
                ok = ok and bool(res.grasped) and abs((res.opening_mm or 0.0) - OBJECT_WIDTH_MM) < 3.0
                extra += f" (object {OBJECT_WIDTH_MM:.0f} mm)"
            summary.add(
                f"gripper {cmd.action}", f"{res.reason}, opening {opening}{extra}, {res.duration_s:.2f} s", ok
            )
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
