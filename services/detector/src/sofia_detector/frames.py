"""Camera-frame clouds into the base frame: ``T_base_cam = T_base_flange(stamp) @ T_flange_cam``,
``T_flange_cam`` from the calibrator or a file, ``T_base_flange`` interpolated from recent flange poses."""

from __future__ import annotations

import logging
import threading
from bisect import bisect_left, insort
from collections import deque
from pathlib import Path

import numpy as np
from sofia_schemas.files import FileContentError, load_json_or_yaml
from sofia_schemas.messages import FlangePose
from sofia_schemas.messages.calibration import CameraCorrection
from sofia_schemas.transforms import as_transforms, interpolate_poses, make_transform

from .errors import BadTransformFile, TransformUnavailable

log = logging.getLogger(__name__)
JUMP_BACK_NS = 1_000_000_000  # a pose this much older than the newest starts a new time line
DEFAULT_TOLERANCE_NS = 50_000_000  # a flange pose further than this from the cloud's stamp is not used


def parse_transform(data: object, where: str) -> np.ndarray:
    """(4, 4) ``T_flange_cam`` from a mapping with ``matrix`` (4x4) or ``translation`` and
    ``quaternion_xyzw`` (a CalibrationResult qualifies). Raises BadTransformFile naming ``where``."""
    if not isinstance(data, dict):
        raise BadTransformFile(where, f"expected a mapping, got {type(data).__name__}")
    try:
        if "matrix" in data:
            return as_transforms(np.array(data["matrix"], dtype=np.float64), "matrix", tol=1e-4)
        if "translation" in data and "quaternion_xyzw" in data:
            return make_transform(
                np.array(data["translation"], float), np.array(data["quaternion_xyzw"], float)
            )
    except (ValueError, TypeError) as e:
        raise BadTransformFile(where, str(e)) from None
    raise BadTransformFile(where, f"needs 'matrix' or 'translation' + 'quaternion_xyzw', has {sorted(data)}")


def load_transform_file(path: str | Path) -> np.ndarray:
    """(4, 4) ``T_flange_cam`` from a YAML or JSON file (see :func:`parse_transform`)."""
    try:
        data = load_json_or_yaml(path)
    except OSError as e:
        raise BadTransformFile(path, f"cannot be read: {e.strerror or e}") from None
    except FileContentError as e:
        raise BadTransformFile(path, e.what) from None
    return parse_transform(data, str(path))


def load_correction_file(path: str | Path) -> CameraCorrection:
    """The ``camera_correction`` of a saved calibration (YAML or JSON); identity when it has none."""
    try:
        data = load_json_or_yaml(path)
    except (OSError, FileContentError):
        return CameraCorrection()  # load_transform_file reports the file's problem
    corr = data.get("camera_correction") if isinstance(data, dict) else None
    try:
        return CameraCorrection.model_validate({} if corr is None else corr)
    except ValueError as e:
        raise BadTransformFile(path, f"camera_correction: {e}") from None


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
        self._poses: deque[tuple[int, np.ndarray | FlangePose]] = deque(maxlen=maxlen)
        self._lock = threading.Lock()
        self._arrived = threading.Condition(self._lock)
        self.tolerance_ns = tolerance_ns

    def add(self, stamp_ns: int, T_base_flange: np.ndarray | FlangePose) -> None:
        """Add a (4, 4) matrix or a :class:`FlangePose` (its matrix computed only when asked). A jump
        back of more than ``JUMP_BACK_NS`` clears the history first, as ROS tf does."""
        with self._arrived:
            if self._poses and stamp_ns < self._poses[-1][0] - JUMP_BACK_NS:
                log.warning(
                    "flange pose stamp jumped back %.3f s: clearing %d poses",
                    (self._poses[-1][0] - stamp_ns) / 1e9, len(self._poses),
                )  # fmt: skip
                self._poses.clear()
            if len(self._poses) == self._poses.maxlen:
                self._poses.popleft()
            insort(self._poses, (stamp_ns, T_base_flange), key=lambda p: p[0])  # out of order: sorted in
            self._arrived.notify_all()

    def wait_covered(self, stamp_ns: int, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` for a pose at or after ``stamp_ns``; False on timeout."""
        with self._arrived:
            return self._arrived.wait_for(
                lambda: bool(self._poses) and self._poses[-1][0] >= stamp_ns, timeout_s
            )

    def __len__(self) -> int:
        return len(self._poses)

    def at(self, stamp_ns: int) -> np.ndarray:
        """(4, 4) ``T_base_flange`` at ``stamp_ns``: interpolated between the poses around it when
        both are within the tolerance, else the nearest within it. Raises TransformUnavailable."""
        with self._lock:
            poses = list(self._poses)
        if not poses:
            raise TransformUnavailable(f"no flange pose received yet (cloud stamp {stamp_ns})")
        stamps = [p[0] for p in poses]
        i = bisect_left(stamps, stamp_ns)
        if i < len(stamps) and stamps[i] == stamp_ns:
            return _matrix(poses[i][1])
        if 0 < i < len(stamps) and stamps[i] - stamps[i - 1] <= 2 * self.tolerance_ns:
            (t0, T0), (t1, T1) = poses[i - 1], poses[i]
            return interpolate_poses(_matrix(T0), _matrix(T1), (stamp_ns - t0) / (t1 - t0))
        near = min((j for j in (i - 1, i) if 0 <= j < len(stamps)), key=lambda j: abs(stamps[j] - stamp_ns))
        gap = abs(stamps[near] - stamp_ns)
        if gap > self.tolerance_ns:
            raise TransformUnavailable(
                f"nearest flange pose is {gap / 1e6:.1f} ms from the cloud stamp {stamp_ns} "
                f"(tolerance {self.tolerance_ns / 1e6:.1f} ms)"
            )
        return _matrix(poses[near][1])


def _matrix(pose: np.ndarray | FlangePose) -> np.ndarray:
    """(4, 4) ``T_base_flange`` of a pose as :meth:`FlangeHistory.add` took it."""
    return pose if isinstance(pose, np.ndarray) else pose.matrix()
