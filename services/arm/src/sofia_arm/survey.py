"""Survey: when a pick has no target it can trust, the arm moves so that the calibrated camera
looks straight down at the whole configured board, waits for a detection of a cloud taken there
and picks from it; an object cut by the image border gets a second view centred on it.

Frames: base = ``panda_link0`` (z up), flange = ``panda_link8``, camera = optical frame (z forward,
x right, y down). ``T_flange_cam`` comes from the calibrator's latest result. Views are candidate
flange poses, lowest camera first; the first one that passes the service's safety rules
(:meth:`sofia_arm.safety.Safety.check_plan`) is taken.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import zenoh
from sofia_runtime.client import QueryError, ask
from sofia_schemas import Board
from sofia_schemas.files import FileContentError
from sofia_schemas.keys import Keys
from sofia_schemas.messages import CalibrationResult, DetectedObject, Detection, PickTarget
from sofia_schemas.messages.calibration import read_calibration_file
from sofia_schemas.transforms import apply, invert

from .autocal_io import Progress
from .errors import PhaseFailed, TargetRefused
from .motion import ArmMotion
from .poses import in_image, look_at
from .safety import Safety

# the simulated and the real D435's colour stream at 640 x 480 (the camera's own intrinsics differ
# by a few pixels: the margin covers them)
CAMERA_K = np.array([[615.0, 0.0, 319.5], [0.0, 615.0, 239.5], [0.0, 0.0, 1.0]])
IMAGE_SIZE = (640, 480)
MARGIN_PX = 25.0  # the board's corners at least this far inside the image
HEIGHTS_M = np.arange(0.55, 1.0, 0.05)  # camera above the board surface, lowest (sharpest) first
ROLLS_DEG = (0.0, 90.0, 180.0, 270.0)
CENTRED_HEIGHTS_M = np.arange(0.40, 0.75, 0.05)  # camera above an object in the second view
DETECTION_WAIT_S = 15.0  # for a detection of a cloud taken at the survey pose
MIN_CONFIDENCE = 0.5  # the detector's own floor for a pick
A_EMPTY_M = 0.02  # no object centre this close to where the object was picked: the place is empty
PLACED_TOL_MM = 5.0  # the object seen this close to B: placed
GRASP_CLEARANCE_M = 0.002  # a low object's grasp: the fingertips this far above the lowest allowed height
MIN_GRIP_M = 0.01  # ... while this much of the object stays above them


def calibration(session: zenoh.Session, keys: Keys, transform_file: Path | None = None,
                timeout_s: float = 2.0) -> np.ndarray | None:  # fmt: skip
    """``T_flange_cam`` (4, 4): the calibrator's latest result, else the ``transform_file`` (a saved
    calibration, :func:`read_calibration_file`), else None."""
    try:
        result = ask(session, keys.calibration_result, CalibrationResult, timeout=timeout_s)
        return np.array(result.matrix, dtype=np.float64)
    except QueryError:
        pass
    if transform_file is None:
        return None
    try:
        return read_calibration_file(transform_file)[0]
    except FileContentError as e:
        raise TargetRefused(f"pick_place survey: transform file {e}") from None


def board_corners(board: Board) -> np.ndarray:
    """(4, 3) the corners of the board's top surface, base frame, metres."""
    half = 0.5 * np.array([board.rows * board.field_size[0], board.cols * board.field_size[1]])
    signs = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]], dtype=np.float64)
    corners_board = np.c_[signs * half, np.zeros(4)]
    return apply(board.T_base_board, corners_board)


def views_above(
    p_base: np.ndarray, heights_m: np.ndarray, T_flange_cam: np.ndarray, yaw: float = 0.0
) -> np.ndarray:
    """(len(heights) * 8, 4, 4) flange poses putting the camera straight above ``p_base`` (3,)
    at each height (lowest first), the image turned by ``ROLLS_DEG`` plus or minus ``yaw`` (rad:
    the image's axes along a board's)."""
    roll_set = np.radians(np.array(ROLLS_DEG))
    roll_set = np.r_[roll_set + yaw, roll_set - yaw]
    eyes = np.repeat(np.asarray(p_base, dtype=np.float64)[None] + np.c_[0 * heights_m, 0 * heights_m, heights_m],
                     len(roll_set), axis=0)  # fmt: skip
    rolls = np.tile(roll_set, len(heights_m))
    T_base_cam = look_at(eyes, p_base, rolls)
    return np.asarray(T_base_cam @ invert(T_flange_cam))


def survey_views(board: Board, T_flange_cam: np.ndarray, K: np.ndarray = CAMERA_K,
                 size: tuple[int, int] = IMAGE_SIZE) -> np.ndarray:  # fmt: skip
    """(m, 4, 4) flange poses from which the camera (intrinsics K (3, 3), image ``size``) sees
    every corner of the board, lowest camera first."""
    centre = board.T_base_board[:3, 3]
    T_bf = views_above(centre, HEIGHTS_M, T_flange_cam, board.yaw)
    T_bc = T_bf @ T_flange_cam
    corners = board_corners(board)
    p_cam = np.einsum("nij,kj->nki", invert(T_bc)[:, :3, :3], corners) + invert(T_bc)[:, None, :3, 3]
    sees = in_image(p_cam.reshape(-1, 3), K, size, MARGIN_PX).reshape(len(T_bf), 4).all(axis=1)
    return np.asarray(T_bf[sees])


def pickable(det: Detection, colours: tuple[str, ...] | None = None) -> list[DetectedObject]:
    """Objects of ``det`` confident enough to pick (of the given colours, else on a red field)."""
    objs = [o for o in det.objects if o.confidence >= MIN_CONFIDENCE and not o.truncated]
    if colours is None:
        return [o for o in objs if o.allowed]
    return [o for o in objs if o.colour in colours]


class Detections:
    """Detections published on ``detections`` while open, newest last."""

    def __init__(self, session: zenoh.Session, keys: Keys) -> None:
        self.items: list[Detection] = []
        self.event = threading.Event()
        self.sub = session.declare_subscriber(keys.detections, self._on)

    def _on(self, sample: zenoh.Sample) -> None:
        try:
            self.items.append(Detection.model_validate_json(sample.payload.to_bytes()))
            self.event.set()
        except ValueError:
            pass

    def after(self, stamp_ns: int, timeout_s: float, stop: Callable[[], bool]) -> Detection | None:
        """The first detection of a cloud stamped at or after ``stamp_ns`` (bus time) that saw
        the board, within ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and not stop():
            for d in self.items:
                if d.stamp_ns >= stamp_ns and d.status != "no_board":
                    return d
            self.event.wait(0.1)
            self.event.clear()
        return None

    def close(self) -> None:
        self.sub.undeclare()


def first_safe(safety: Safety, what: str, views: np.ndarray, q_now: np.ndarray,
               command: str = "pick_place") -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """(flange pose (4, 4), joints (7,)) of the first view that passes every safety rule;
    TargetRefused naming ``command`` with the first view's refusal when none does."""
    first: TargetRefused | None = None
    for T in views:
        try:
            return T, safety.check_plan(command, [(what, what, "joints", T)], q_now)[what]
        except TargetRefused as e:
            first = first or e
    if first is None:
        raise TargetRefused(f"{command} {what}: no view of it with the camera {IMAGE_SIZE} px")
    raise TargetRefused(
        f"{command} {what}: none of {len(views)} views passes the safety rules; the first: {first}"
    )


def pick_of(obj: DetectedObject, stamp_ns: int, safety: Safety) -> PickTarget:
    """The detector's top-down pick of ``obj`` (fingertips at its centre), with this tool's offset.

    An object whose centre lies closer to the surface than its margin allows (a low object, a
    board lower than configured) is held higher: the fingertips at the lowest allowed height plus
    ``GRASP_CLEARANCE_M``, while that leaves at least ``MIN_GRIP_M`` of the object above them."""
    from sofia_detector.pick import PickParams, pick_target

    offset = safety.tool.fingertip_offset_m or PickParams().fingertip_offset
    params = PickParams(fingertip_offset=offset, max_opening_mm=safety.config.gripper_max_opening_mm)
    target = pick_target(obj, stamp_ns, params=params)
    floor = safety.surface.lowest_allowed + GRASP_CLEARANCE_M
    top = obj.center[2] + obj.extents[2] / 2
    dz = floor - obj.center[2]
    if dz > 0 and floor <= top - MIN_GRIP_M:
        up = np.array([0.0, 0.0, dz])
        target = target.model_copy(update={
            "grasp_translation": tuple(float(v) for v in np.array(target.grasp_translation) + up),
            "pregrasp_translation": tuple(float(v) for v in np.array(target.pregrasp_translation) + up),
        })  # fmt: skip
    return target


class Survey:
    """Looks for an object to pick (:meth:`find`) from the survey pose, then centred on it."""

    def __init__(self, arm: ArmMotion, safety: Safety, progress: Progress, detections: Detections,
                 board: Board, T_flange_cam: np.ndarray, speed: float) -> None:  # fmt: skip
        self.arm, self.safety, self.progress, self.detections = arm, safety, progress, detections
        self.board, self.T_fc, self.speed = board, T_flange_cam, speed
        self.moved = False
        self.command = "pick_place"  # named in refusals

    def _look(self, name: str, views: np.ndarray, text: str) -> Detection:
        """Go to the first safe view (TargetRefused when none is and nothing moved yet), wait
        until still, and return a detection of a cloud taken there."""
        t0 = time.monotonic()
        try:
            T, q = first_safe(self.safety, name, views, self.arm.q(), self.command)
        except TargetRefused as e:
            if not self.moved:
                raise
            raise PhaseFailed(name, str(e)) from None
        self.moved = True
        res = self.arm.move_joints(q, self.speed)
        if not res.ok:
            raise PhaseFailed(name, f"{res.status}: {res.reason}", res.status)
        self.arm.wait_still(5.0)
        stamp_ns = self.arm.stamp_ns()
        self.progress.add(
            name, "done", f"{text}, flange at {np.round(T[:3, 3], 3).tolist()} m", time.monotonic() - t0
        )
        det = self.detections.after(stamp_ns, DETECTION_WAIT_S, lambda: False)
        if det is None:
            raise PhaseFailed(name, f"no detection of a cloud taken there within {DETECTION_WAIT_S:g} s "
                                    "(is the detector running?)")  # fmt: skip
        return det

    def find(self, colours: tuple[str, ...] | None = None,
             exclude_near: np.ndarray | None = None) -> tuple[DetectedObject, int]:  # fmt: skip
        """An object to pick (of ``colours``, else on a red field; none within ``A_EMPTY_M`` of
        ``exclude_near`` (3,), base frame: one already placed) and the stamp of its detection;
        PhaseFailed when there is none."""
        det = self._look(
            "survey", survey_views(self.board, self.T_fc), "camera straight above the board centre"
        )
        what = "on a red field" if colours is None else f"of colour {'/'.join(colours)}"

        def away(o: DetectedObject) -> bool:
            return (
                exclude_near is None
                or float(np.linalg.norm(np.array(o.center[:2]) - exclude_near[:2])) > A_EMPTY_M
            )

        objs = [o for o in pickable(det, colours) if away(o)]
        if not objs:
            cut = [
                o for o in det.objects if (o.allowed if colours is None else o.colour in colours) and away(o)
            ]
            if not cut:
                names = [f"{o.colour or '?'} ({o.confidence:.2f})" for o in det.objects]
                raise PhaseFailed("survey", f"no object {what} in view (seen: {names or 'none'})")
            o = cut[0]
            det = self._look("second view", views_above(np.array(o.center), CENTRED_HEIGHTS_M, self.T_fc),
                             f"centred on the object at {np.round(o.center, 3).tolist()} m (confidence "
                             f"{o.confidence:.2f}, {', '.join(o.truncated) or 'not truncated'})")  # fmt: skip
            objs = [o for o in pickable(det, colours) if away(o)]
            if not objs:
                raise PhaseFailed("second view", f"still no object {what} to pick in view")
        return objs[0], det.stamp_ns

    def verify(self, A_base: np.ndarray, B_base: np.ndarray) -> dict[str, object]:
        """Back at the survey pose, a fresh detection: the horizontal distance (mm) of the nearest
        object to B (3,) and whether the pick place A (3,) is empty (base frame, m)."""
        det = self._look("verify", survey_views(self.board, self.T_fc), "camera above the board again")
        centres = np.array([o.center for o in det.objects], dtype=np.float64).reshape(-1, 3)
        to_B = np.linalg.norm(centres[:, :2] - B_base[:2], axis=1)
        to_A = np.linalg.norm(centres[:, :2] - A_base[:2], axis=1)
        placed_mm = float(1e3 * to_B.min()) if len(centres) else float("inf")
        a_empty = bool(np.all(to_A > A_EMPTY_M))
        self.progress.add("seen at B", "done" if placed_mm <= PLACED_TOL_MM and a_empty else "failed",
                          f"object {placed_mm:.1f} mm from B, A {'empty' if a_empty else 'NOT empty'} "
                          f"({len(centres)} objects seen)")  # fmt: skip
        return {"placed_error_mm": round(placed_mm, 2), "a_empty": a_empty, "objects_seen": len(centres)}

    def verify_colours(self, places: dict[str, np.ndarray]) -> dict[str, float]:
        """Back at the survey pose, a fresh detection: for each colour, the horizontal distance (mm)
        of the nearest object of that colour to its place (3,), base frame (inf: none seen)."""
        det = self._look("verify", survey_views(self.board, self.T_fc), "camera above the board again")
        out: dict[str, float] = {}
        for colour, B in places.items():
            d = [np.linalg.norm(np.array(o.center[:2]) - B[:2]) for o in det.objects if o.colour == colour]
            out[colour] = round(float(1e3 * min(d)), 2) if d else float("inf")
        ok = all(v <= PLACED_TOL_MM for v in out.values())
        self.progress.add("seen at the places", "done" if ok else "failed",
                          ", ".join(f"{c} {v:.1f} mm" for c, v in out.items()))  # fmt: skip
        return out
