"""The demo's closed loop in the simulated cell: franky-sim behind the arm service, the simulated
D435 rendering from the live flange pose, the calibrator, the detector and the emulated gripper.

Steps: the arm calibrates the camera by itself (result against the camera's true T_flange_cam),
the detector finds the object on the board through that calibration (against the true centre),
the arm surveys the board, picks the object at A and sets it down at B (grasp pose against the true
centre, gripper grasped), then sees it at B and A empty. The camera, the gripper emulator and the
arm share the simulated world (``SOFIA_SIM_WORLD``): the object moves with the fingers. Last, the
lab's sorting task (:mod:`.sort_step`): three colours onto their places, a distractor left alone.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import zenoh
from sofia_runtime import zenoh_config
from sofia_runtime.client import QueryError, ask
from sofia_schemas import Board, Keys
from sofia_schemas.messages import ArmCommand, ArmPhase, ArmResult, Detection
from sofia_schemas.sim_world import ENV_SIM_WORLD
from sofia_schemas.transforms import rotation_angle

from .bus import Collector, wait_until
from .launcher import Launcher, ServiceSpec, all_ready, board_args
from .sort_step import sort_step
from .steps import sofia
from .summary import Summary, say
from .wording import field_text, transform_text

SPEED = 1.0  # franky-sim at full relative speed (a real arm: the service's limits cap it)


def _truth(scene: str, robot: str) -> dict:
    out = sofia("camera", "sim-truth", "--sim-scene", scene, "--json", env_robot=robot, timeout=120)
    if out.returncode != 0:
        raise RuntimeError(f"sofia camera sim-truth: {out.stderr[-500:]}")
    return dict(json.loads(out.stdout))


def _camera(
    scene: str, log_dir: Path, robot: str, env: dict[str, str], extra: list[str] | None = None
) -> Launcher:
    cam = Launcher([ServiceSpec("camera", ["camera", "serve", "--sim", "--sim-scene", scene, *(extra or [])], "camera")],
                   log_dir, robot, env)  # fmt: skip
    cam.start()
    return cam


def _healthy(session: zenoh.Session, launchers: list[Launcher], timeout: float) -> bool:
    def ok() -> bool:
        for la in launchers:
            la.poll()
        return all(all_ready(la.check_health(session)) for la in launchers)

    return wait_until(ok, timeout)


def _ask_arm(session: zenoh.Session, keys: Keys, cmd: ArmCommand) -> ArmResult:
    def show(p: ArmPhase) -> None:
        say(f"  {p.line()}")

    progress = Collector(session, keys.arm_progress, ArmPhase, show)
    try:
        return ask(session, keys.arm_command, ArmResult, cmd.model_dump_json(), timeout=cmd.timeout_s + 30)
    finally:
        progress.close()


def calibrate(session: zenoh.Session, keys: Keys, T_true: np.ndarray, summary: Summary) -> bool:
    say("autonomous calibration: the arm shows the blob to the simulated camera ...")
    t0 = time.monotonic()
    try:
        res = _ask_arm(session, keys, ArmCommand(command="calibrate", speed=SPEED, timeout_s=400))
    except QueryError as e:
        summary.add("autonomous calibration", str(e), False)
        return False
    r = res.details.get("result")
    if r is None:
        summary.add("autonomous calibration", f"{res.status}: {res.reason}", False)
        return False
    T = np.array(r["matrix"])
    dt_mm = 1e3 * float(np.linalg.norm(T[:3, 3] - T_true[:3, 3]))
    dr_deg = float(np.degrees(rotation_angle(T[:3, :3].T @ T_true[:3, :3])))
    say(
        f"  T_flange_cam translation {np.round(T[:3, 3], 4).tolist()} m, truth {np.round(T_true[:3, 3], 4).tolist()} m"
    )
    say(f"  ROS 1: {r.get('ros1_static_transform', '')}")
    ok = res.ok and dt_mm < 2.0 and dr_deg < 0.3
    summary.add("autonomous calibration", f"{res.details.get('samples')} poses; {dt_mm:.2f} mm / "
                f"{dr_deg:.3f} deg from the camera's true T_flange_cam, translation 1-sigma "
                f"{max(res.details.get('sigma_translation_mm', r['std_translation_mm'])):.2f} mm; "
                f"{time.monotonic() - t0:.0f} s", ok)  # fmt: skip
    return ok


def detect(session: zenoh.Session, keys: Keys, center_true: np.ndarray, summary: Summary) -> bool:
    dets = Collector(session, keys.detections, Detection)
    found = wait_until(lambda: any(d.objects and d.transform for d in dets.items), 30)
    dets.close()
    if not found:
        summary.add("detect (live camera)", f"no object detected in {len(dets)} detections", False)
        return False
    det = next(d for d in reversed(dets.items) if d.objects and d.transform)
    err = 1e3 * float(np.linalg.norm(np.array(det.objects[0].center) - center_true))
    summary.add("detect (live camera)", f"object on {field_text(det.objects[0])}, {err:.1f} mm from the true "
                f"centre, seen through {transform_text(det.transform or '')}", err < 3.0)  # fmt: skip
    return err < 3.0


def place_b(board: Board, a_base: np.ndarray) -> np.ndarray:
    """(3,) B: the centre of the red field farthest from A (3,), on the board's surface (base frame)."""
    fields = np.array([board.field_center_base(r, c) for r, c in board.allowed])
    return np.asarray(fields[np.argmax(np.linalg.norm(fields[:, :2] - a_base[:2], axis=1))])


def pick_place(
    session: zenoh.Session, keys: Keys, center_true: np.ndarray, board: Board, summary: Summary
) -> None:
    B = place_b(board, center_true)
    say(f"pick and place: survey, pick the object at A, set it down at B = {np.round(B, 3).tolist()} ...")
    try:
        res = _ask_arm(session, keys, ArmCommand(command="pick_place", place_object=tuple(B), speed=SPEED,  # type: ignore[arg-type]
                                                 timeout_s=400))  # fmt: skip
    except QueryError as e:
        summary.add("pick and place", str(e), False)
        return
    reached = res.details.get("reached", {})
    offset = res.details.get("target", {}).get("fingertip_offset_m", 0.2)
    seen = res.details.get("seen", {})
    if not res.ok or "grasp" not in reached or not seen:
        summary.add("pick and place", f"{res.status}: {res.reason}", False)
        return
    grasp_err = 1e3 * float(
        np.linalg.norm(np.array(reached["grasp"]["position"]) - center_true - [0, 0, offset])
    )
    grasped = any(p.name == "grasp" and "grasped True" in p.reason for p in res.phases)
    ok = grasped and grasp_err < 2.0 and seen["placed_error_mm"] <= 5.0 and seen["a_empty"]
    summary.add("pick and place", f"{'object held' if grasped else 'NOTHING held'}; grasp pose {grasp_err:.2f} mm "
                f"from the true one (centre + fingertip offset); detected again {seen['placed_error_mm']:.1f} mm "
                f"from B, A {'empty' if seen['a_empty'] else 'NOT empty'}; {res.duration_s:.0f} s", ok)  # fmt: skip


def run_cell(out: Path, robot: str, board: Path | None, summary: Summary) -> None:
    """The closed loop on its own key space (``{robot}-cell``), services started and stopped here."""
    cell = f"{robot}-cell"
    keys, log_dir = Keys(cell), out / "logs-cell"
    calib_truth, board_truth = _truth("calibration", cell), _truth("board", cell)
    obj = board_truth["objects"][0]
    world = out / "world-cell.json"  # the simulated world: camera, gripper emulator and arm share it
    world.unlink(missing_ok=True)
    env = dict(os.environ, **{ENV_SIM_WORLD: str(world)})
    services = Launcher([
        ServiceSpec("arm", ["arm", "serve", "--sim", "--max-speed", str(SPEED), *board_args(board)], "arm"),
        ServiceSpec("calibrator", ["calibrator", "serve", "--state-dir", str(out / "calibrator-cell")], "calibrator"),
        ServiceSpec("detector", ["detector", "serve", *board_args(board)], "detector"),
        ServiceSpec("gripper", ["gripper", "serve", "--emulate"], "gripper"),
    ], log_dir, cell, env)  # fmt: skip
    say(f"starting the simulated cell (franky-sim, camera --sim, world {world}, logs in {log_dir}) ...")
    services.start()
    camera = _camera("calibration", log_dir, cell, env)
    try:
        with zenoh.open(zenoh_config()) as session:
            healthy = _healthy(session, [services, camera], 120)
            summary.add("cell up", "arm (franky-sim), camera (sim), calibrator, detector, gripper healthy"
                        if healthy else "not all healthy", healthy)  # fmt: skip
            if not healthy or not calibrate(session, keys, np.array(calib_truth["T_flange_cam"]), summary):
                return
            camera.stop()  # the board with the object in front of the same camera
            camera = _camera("board", log_dir, cell, env)
            _healthy(session, [camera], 60)
            center = np.array(obj["center"])
            if detect(session, keys, center, summary):
                pick_place(session, keys, center, Board.load(board), summary)
            camera.stop()  # the sorting task: three colours and a distractor, a new world
            world.unlink(missing_ok=True)
            camera = _camera("board", log_dir, cell, env, ["--sim-kind", "sort"])
            _healthy(session, [camera], 60)
            sort_step(session, keys, Board.load(board), world, SPEED, _ask_arm, summary)
    finally:
        camera.stop()
        services.stop()
