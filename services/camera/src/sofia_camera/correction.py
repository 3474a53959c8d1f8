"""The calibration's depth correction, applied by the camera so that every consumer gets
corrected clouds (and knows it: :class:`~sofia_camera.meta.CloudMeta`, status ``depth_correction``).

The calibrator may estimate, together with ``T_flange_cam``, how the camera's depth is off
(``CalibrationResult.camera_correction``: a depth scale, maybe an offset). The camera service
follows the newest result on the bus; a result without a correction (or an identity one)
switches it off.
"""

from __future__ import annotations

import logging
import threading
from typing import Any

import numpy as np
from pydantic import ValidationError
from sofia_schemas.messages import CalibrationResult

log = logging.getLogger(__name__)


class DepthCorrection:
    """The correction in force (thread-safe; ``enabled`` False: never applied)."""

    def __init__(self, enabled: bool = True) -> None:
        self.enabled = enabled
        self._lock = threading.Lock()
        self.correction: Any = None  # a sofia_schemas CameraCorrection, not identity
        self.source = ""
        self.errors = 0
        self.last_error = ""

    def on_result(self, payload: bytes) -> None:
        """A JSON CalibrationResult from the calibrator (the subscriber's callback)."""
        try:
            result = CalibrationResult.model_validate_json(payload)
        except (ValidationError, ValueError) as e:
            self.errors += 1
            self.last_error = f"calibration result is invalid: {str(e)[:300]}"
            log.warning("%s", self.last_error)
            return
        self.use(getattr(result, "camera_correction", None), f"calibrator result {result.stamp_ns}")

    def use(self, correction: Any, source: str) -> None:
        active = correction is not None and not getattr(correction, "is_identity", False)
        with self._lock:
            self.correction = correction if active else None
            self.source = source if active else ""
        if active:
            log.info("depth correction from %s: %s", source, self.describe())

    def current(self) -> tuple[Any, str]:
        """(correction or None, where it came from); None when disabled or identity."""
        with self._lock:
            if not self.enabled or self.correction is None:
                return None, ""
            return self.correction, self.source

    def apply(self, points_cam: np.ndarray, correction: Any) -> np.ndarray:
        """(n, 3) camera-frame points, metres -> corrected (n, 3) float32."""
        return np.asarray(correction.apply(points_cam), dtype=np.float32)

    def describe(self) -> str:
        corr, source = self.current()
        if not self.enabled:
            return "off (--depth-correction off)"
        if corr is None:
            return "none (no correction in the calibration result)"
        return (f"applied: {corr.model}, scale {corr.depth_scale:.5f}, offset {corr.depth_offset_m * 1e3:.2f} mm "
                f"({source})")  # fmt: skip
