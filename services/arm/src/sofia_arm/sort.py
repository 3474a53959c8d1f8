"""Sort by colour (``sort_colours``): every object of the given colours picked and set down at its
colour's place, colour by colour in the command's order, with a survey before each pick (the
previous pick changed the board), and a last survey that checks where each colour ended up.

Before the first motion, the place poses of every colour (with a nominal object, fingers down)
and the survey pose are checked by the service's safety rules; each pick is checked again in
full (:func:`sofia_arm.pick_place.check_pick_place`) before it moves.
"""

from __future__ import annotations

import time

import numpy as np
import zenoh
from sofia_schemas import Board
from sofia_schemas.keys import Keys
from sofia_schemas.messages import ArmCommand, ArmResult, PickTarget
from sofia_schemas.transforms import matrix_to_quat_xyzw

from . import survey
from .autocal_io import Progress
from .config import ArmConfig
from .errors import PhaseFailed, TargetRefused
from .motion import ArmMotion
from .pick_place import PickPlace, bus_gripper, check_pick_place, place_of, plan_poses, plan_steps
from .safety import Safety

MAX_PER_COLOUR = 3  # objects of one colour picked at most (a guard against a place the camera misreads)
NOMINAL_CENTRE_M = 0.03  # object centre height above the surface for the up-front check of the places


def nominal_target(B: np.ndarray, fingertip_offset_m: float) -> PickTarget:
    """A pick target standing for an object at B (3,), fingers down, for checking the places."""
    centre = B + np.array([0.0, 0.0, NOMINAL_CENTRE_M])
    grasp = centre + np.array([0.0, 0.0, fingertip_offset_m])
    return PickTarget(stamp_ns=0, object_center=tuple(centre), grasp_translation=tuple(grasp),  # type: ignore[arg-type]
                      pregrasp_translation=tuple(grasp + np.array([0.0, 0.0, 0.1])), rotation_xyzw=(1.0, 0.0, 0.0, 0.0),  # type: ignore[arg-type]
                      yaw=0.0, opening_mm=80.0, fingertip_offset_m=fingertip_offset_m)  # fmt: skip


def check_sort(cmd: ArmCommand, safety: Safety, q_start: np.ndarray) -> None:
    """The place poses of every colour, checked from ``q_start`` (7,); TargetRefused naming the
    colour, the pose and the rule."""
    for colour, B in cmd.places_by_colour.items():
        if B[2] < safety.surface.z - 1e-3:
            raise TargetRefused(f"sort_colours place of {colour} {list(B)} m is below the surface "
                                f"({safety.surface.source})")  # fmt: skip
        target = nominal_target(np.array(B), safety.tool.fingertip_offset_m or 0.2)
        place = place_of(ArmCommand(command="pick_place", target=target, place_object=B), target, safety)
        steps = [
            s
            for s in plan_steps(plan_poses(target, place["position"], None))
            if s[0] in ("move", "lower", "retreat")
        ]
        safety.check_plan(f"sort_colours {colour}", steps, q_start)


def run_sort(cmd: ArmCommand, arm: ArmMotion, session: zenoh.Session, keys: Keys) -> ArmResult:
    """The arm service's ``sort_colours`` command."""
    t0 = time.monotonic()
    safety: Safety = getattr(arm, "safety", None) or Safety(ArmConfig())
    check_sort(cmd, safety, arm.q())
    T_flange_cam = survey.calibration(session, keys, safety.config.transform_file)
    if T_flange_cam is None:
        raise TargetRefused(
            "sort_colours needs the camera's calibration: run the calibrator or give the arm --transform"
        )
    board = Board.from_file(safety.config.board_file) if safety.config.board_file else Board.default()
    views = survey.survey_views(board, T_flange_cam)
    survey.first_safe(safety, "survey", views, arm.q(), "sort_colours")  # refused: nothing moved
    progress = Progress(session, keys)
    look = survey.Survey(
        arm, safety, progress, survey.Detections(session, keys), board, T_flange_cam, cmd.speed
    )
    look.command = "sort_colours"
    places = {c: np.array(B) for c, B in cmd.places_by_colour.items()}
    sorted_: list[dict[str, object]] = []
    errors: list[str] = []
    try:
        for colour, B in places.items():
            for k in range(MAX_PER_COLOUR):
                t = time.monotonic()
                entry: dict[str, object] = {"colour": colour, "place": B.tolist()}
                try:
                    obj, stamp_ns = look.find((colour,), exclude_near=B)
                except PhaseFailed as e:
                    if k == 0:  # none of this colour at all
                        errors.append(f"{colour}: {e.reason}")
                        sorted_.append(
                            {**entry, "error": e.reason, "duration_s": round(time.monotonic() - t, 1)}
                        )
                    break
                target = survey.pick_of(obj, stamp_ns, safety)
                entry["from"] = [round(v, 4) for v in target.object_center]
                try:
                    sub = ArmCommand(command="pick_place", target=target, place_object=tuple(B))  # type: ignore[arg-type]
                    place = place_of(sub, target, safety)
                    planned = check_pick_place(sub, target, safety, arm.q())
                    PickPlace(arm, bus_gripper(session, keys), cmd.speed, progress).run(
                        target, place, planned
                    )
                except (PhaseFailed, TargetRefused) as e:
                    entry["error"] = str(e)
                    errors.append(f"{colour}: {e}")
                entry["duration_s"] = round(time.monotonic() - t, 1)
                progress.add(f"{colour} {k + 1}", "failed" if "error" in entry else "done",
                             f"from {entry['from']} to {np.round(B, 3).tolist()} m in {entry['duration_s']} s")  # fmt: skip
                sorted_.append(entry)
                if "error" in entry:
                    break
        seen = look.verify_colours(places)
    except PhaseFailed as e:
        errors.append(str(e))
        seen = {}
    finally:
        look.detections.close()
        progress.close()
    for colour, mm in seen.items():
        if mm > survey.PLACED_TOL_MM:
            errors.append(f"{colour}: seen {mm:.1f} mm from its place")
    T = arm.T_base_flange()
    return ArmResult(
        ok=not errors, command="sort_colours", status="failed" if errors else "done", reason="; ".join(errors),
        q=tuple(float(v) for v in arm.q()), position=tuple(float(v) for v in T[:3, 3]),  # type: ignore[arg-type]
        quaternion_xyzw=tuple(float(v) for v in matrix_to_quat_xyzw(T[:3, :3])),  # type: ignore[arg-type]
        duration_s=round(time.monotonic() - t0, 3), phases=progress.phases,
        details={"sorted": sorted_, "seen_error_mm": seen},
    )  # fmt: skip
