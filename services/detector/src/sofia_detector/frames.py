"""Camera-frame clouds into the base frame: ``T_base_cam = T_base_flange(stamp) @ T_flange_cam``,
``T_flange_cam`` from the calibrator or a file, ``T_base_flange`` interpolated from recent flange poses."""

from __future__ import annotations

import logging
import threading

import numpy as np
from sofia_schemas.messages import FlangePose
from sofia_schemas.messages.calibration import CameraCorrection
from sofia_schemas.transforms import PoseTimeline

from .errors import TransformUnavailable

log = logging.getLogger(__name__)
JUMP_BACK_NS = 1_000_000_000  # a pose this much older than the newest starts a new time line
DEFAULT_TOLERANCE_NS = 50_000_000  # a flange pose further than this from the cloud's stamp is not used


def points_to_base(
    points_cam: np.ndarray, T_base_cam: np.ndarray, correction: CameraCorrection | None = None
) -> np.ndarray:
    """Measured camera-frame points into the base frame, the (affine) correction folded into one map.

    points_cam: (..., 3) float (any strides: a view of the received bytes), camera optical frame,
    metres, NaN kept. T_base_cam: (4, 4). Returns (..., 3) float32 points_base: the one array
    allocated (no intermediate copy of the cloud)."""
    A = np.eye(4)
    if correction is not None:  # the affine map of CameraCorrection.apply, read off the basis
        A[:3, 3] = correction.apply(np.zeros(3))
        A[:3, :3] = (correction.apply(np.eye(3)) - A[:3, 3]).T
    M = T_base_cam @ A
    out = np.empty(points_cam.shape, np.float32)
    with np.errstate(invalid="ignore", over="ignore"):
        np.matmul(points_cam, M[:3, :3].T.astype(np.float32), out=out)
        out += M[:3, 3].astype(np.float32)
    return out


class FlangeHistory:
    """The last ``maxlen`` flange poses, looked up by stamp (thread-safe)."""

    def __init__(self, maxlen: int = 400, tolerance_ns: int = DEFAULT_TOLERANCE_NS) -> None:
        self._poses = PoseTimeline(maxlen)
        self._lock = threading.Lock()
        self._arrived = threading.Condition(self._lock)
        self.tolerance_ns = tolerance_ns

    def add(self, stamp_ns: int, T_base_flange: np.ndarray | FlangePose) -> None:
        """Add a (4, 4) matrix or a :class:`FlangePose` (its matrix computed only when asked). A jump
        back of more than ``JUMP_BACK_NS`` clears the history first, as ROS tf does."""
        with self._arrived:
            stamps = self._poses.stamps_ns
            if stamps and stamp_ns < stamps[-1] - JUMP_BACK_NS:
                log.warning(
                    "flange pose stamp jumped back %.3f s: clearing %d poses",
                    (stamps[-1] - stamp_ns) / 1e9, len(stamps),
                )  # fmt: skip
                self._poses.clear()
            self._poses.add(stamp_ns, T_base_flange)
            self._arrived.notify_all()

    def wait_covered(self, stamp_ns: int, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` for a pose at or after ``stamp_ns``; False on timeout."""
        stamps = self._poses.stamps_ns
        with self._arrived:
            return self._arrived.wait_for(lambda: bool(stamps) and stamps[-1] >= stamp_ns, timeout_s)

    def __len__(self) -> int:
        return len(self._poses)

    def at(self, stamp_ns: int) -> np.ndarray:
        """(4, 4) ``T_base_flange`` at ``stamp_ns``: interpolated between the poses around it when
        both are within the tolerance, else the nearest within it. Raises TransformUnavailable."""
        with self._lock:
            try:
                return self._poses.at(stamp_ns, self.tolerance_ns, 2 * self.tolerance_ns)
            except LookupError as e:
                raise TransformUnavailable(str(e)) from None
