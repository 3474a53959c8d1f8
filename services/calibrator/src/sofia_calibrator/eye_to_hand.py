"""Eye-to-hand: the camera fixed in the world, the target (a ball or blob) on the flange.

``p_cam_i = T_cam_base T_base_flange_i p_flange`` is the eye-in-hand observation
(``p_cam_i = T_cam_flange T_flange_base_i p_base``) with the flange poses inverted: the same fit,
outlier test and diagnostics apply, ``T_flange_cam`` read as ``T_base_cam`` and ``p_base`` as the
target in the flange frame; the result's frames are the base's and the camera's.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sofia_schemas.transforms import as_transforms, invert

from .errors import InputMismatch
from .fitting.calibrate import Calibration, calibrate

BASE_FRAME = "panda_link0"
CAMERA_FRAME = "camera_link_optical"
SETUPS = ("eye-in-hand", "eye-to-hand")


def flange_base_poses(T_base_flange: np.ndarray) -> np.ndarray:
    """(n, 4, 4) T_flange_base of (n, 4, 4) flange poses (rigid inverses, validated)."""
    T = np.asarray(as_transforms(T_base_flange, "T_base_flange"), dtype=np.float64)
    if T.ndim != 3:
        raise InputMismatch(f"T_base_flange must be (n, 4, 4), got {T.shape}")
    return invert(T)


def calibrate_eye_to_hand(
    p_cam: np.ndarray,
    T_base_flange: np.ndarray,
    *,
    parent_frame: str = BASE_FRAME,
    child_frame: str = CAMERA_FRAME,
    **options: Any,
) -> Calibration:
    """Calibrate a fixed camera from a flange-mounted target seen from n flange poses.

    p_cam: (n, 3) target, camera optical frame, metres. T_base_flange: (n, 4, 4) flange poses in
    the base frame. options: those of :func:`calibrate` (``guess``: a (4, 4) T_base_cam).
    Returns a :class:`Calibration` whose ``T_flange_cam`` is T_base_cam (parent ``parent_frame``,
    the base) and whose ``p_base`` is the target in the flange frame (metres); ``map_to_base``
    then maps a camera point into the flange frame of its sample.
    """
    T_flange_base = flange_base_poses(T_base_flange)
    return calibrate(p_cam, T_flange_base, parent_frame=parent_frame, child_frame=child_frame, **options)


def calibrate_setup(
    p_cam: np.ndarray, T_base_flange: np.ndarray, setup: str = "eye-in-hand", **options: Any
) -> Calibration:
    """:func:`calibrate` (eye-in-hand) or :func:`calibrate_eye_to_hand`, by ``setup``."""
    if setup not in SETUPS:
        raise InputMismatch(f"setup must be one of {SETUPS}, got {setup!r}")
    if setup == "eye-to-hand":
        return calibrate_eye_to_hand(p_cam, T_base_flange, **options)
    return calibrate(p_cam, T_base_flange, **options)
