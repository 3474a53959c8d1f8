"""Where a pick's target comes from when the command gives none: a survey of the board
(:mod:`sofia_arm.survey`) through the camera's calibration, else the detector's next published
pick target."""

from __future__ import annotations

import threading

import numpy as np
import zenoh
from sofia_schemas import Board
from sofia_schemas.keys import Keys
from sofia_schemas.messages import PickTarget

from . import survey
from .autocal_io import Progress
from .errors import PhaseFailed
from .motion import ArmMotion
from .safety import Safety

TARGET_WAIT_S = 5.0  # how long to wait for a pick target on the bus when none is given


def latest_target(session: zenoh.Session, keys: Keys, timeout_s: float = TARGET_WAIT_S) -> PickTarget:
    """The next :class:`PickTarget` published on ``pick/target`` within ``timeout_s``."""
    got: list[PickTarget] = []
    event = threading.Event()

    def on_target(s: zenoh.Sample) -> None:
        try:
            got.append(PickTarget.model_validate_json(s.payload.to_bytes()))
            event.set()
        except ValueError:
            pass

    sub = session.declare_subscriber(keys.pick_target, on_target)
    try:
        if not event.wait(timeout_s):
            raise PhaseFailed("target", f"no pick target given and none published on {keys.pick_target} "
                                        f"within {timeout_s} s (is the detector running and seeing an object on a red field? "
                                        "It publishes none for objects below its --pick-min-confidence, such as "
                                        "objects cut by the image border: see `sofia health detector`, picks_withheld)")  # fmt: skip
        return got[-1]
    finally:
        sub.undeclare()


def find_target(arm: ArmMotion, safety: Safety, session: zenoh.Session, keys: Keys, progress: Progress,
                speed: float, colours: tuple[str, ...] | None = None) -> tuple[PickTarget, survey.Survey | None]:  # fmt: skip
    """A target to pick found by a survey (:mod:`sofia_arm.survey`) through the calibrator's latest
    result (or the configured transform), and the survey (close its detections); without either,
    the detector's next published target and None."""
    T_flange_cam = survey.calibration(session, keys, safety.config.transform_file)
    if T_flange_cam is None:
        target = latest_target(session, keys)
        progress.add("target", "done", f"object at {np.round(target.object_center, 4).tolist()} m "
                                       "(published; no calibration on the bus to survey with)")  # fmt: skip
        return target, None
    board = Board.from_file(safety.config.board_file) if safety.config.board_file else Board.default()
    look = survey.Survey(arm, safety, progress, survey.Detections(session, keys), board, T_flange_cam, speed)
    try:
        obj, stamp_ns = look.find(colours)
    except BaseException:
        look.detections.close()
        raise
    target = survey.pick_of(obj, stamp_ns, safety)
    progress.add("target", "done", f"{obj.colour or ''} object at {np.round(target.object_center, 4).tolist()} m, "
                                   f"confidence {obj.confidence:.2f}".lstrip())  # fmt: skip
    return target, look
