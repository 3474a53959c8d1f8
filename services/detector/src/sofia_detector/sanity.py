"""Why a cloud shows no board: the usual mistakes (millimetres, the camera's frame), said plainly."""

from __future__ import annotations

import numpy as np
from sofia_schemas import Board

MM_SCALE = 20.0  # a median distance from the origin beyond this many metres is millimetres
CAMERA_MIN_Z = 0.1  # every point this far along z: depths in front of a camera


def diagnose(points: np.ndarray, board: Board) -> str | None:
    """What is wrong with a cloud in which no board was found, or None when nothing obvious.

    points: (N, 3) or (H, W, 3), meant to be in the board's frame, metres.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    with np.errstate(invalid="ignore", over="ignore"):
        p = p[np.isfinite(p).all(axis=1)]
    if p.shape[0] == 0:
        return "it has no finite points"
    dist = float(np.median(np.linalg.norm(p, axis=1)))
    if dist > MM_SCALE:
        return (
            f"its points lie a median {dist:.0f} m from the origin: the coordinates look like "
            "millimetres; give metres"
        )
    z = p[:, 2]
    if float(np.percentile(z, 2)) > CAMERA_MIN_Z + board.surface_z and float(np.median(z)) < 5.0:
        return (
            f"every point has z > {CAMERA_MIN_Z} m (median {float(np.median(z)):.2f} m) like depths in "
            f"front of a camera: it looks like a camera-frame cloud; sofia detect takes clouds in "
            f"{board.frame_id!r} (map it with the flange pose and T_flange_cam, or record the base-frame topic)"
        )
    return None
