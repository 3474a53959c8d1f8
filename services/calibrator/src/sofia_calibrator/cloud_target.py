"""The calibration point the live service takes from each camera cloud (``serve --from-clouds``):
the blob on the sheet (:func:`sofia_calibrator.blob.find_blob`) or a ball
(:func:`sofia_calibrator.targets.ball.find_ball`), with its confidence."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputMismatch

CLOUD_TARGETS = ("blob", "ball")


@dataclass
class CloudTarget:
    """``kind``: blob or ball; ``radius_m``: the ball's radius (metres; None: fitted per view)."""

    kind: str = "blob"
    radius_m: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in CLOUD_TARGETS:
            raise InputMismatch(f"cloud target must be one of {list(CLOUD_TARGETS)}, got {self.kind!r}")

    def find(self, points_cam: np.ndarray, rgb: np.ndarray) -> tuple[np.ndarray, float]:
        """(p_cam (3,) camera optical frame m, confidence 0..1) of the target in an organized cloud
        points_cam (H, W, 3) with colours rgb (H, W, 3) uint8; raises CalibrationError when absent."""
        if self.kind == "ball":
            from .targets.ball import find_ball

            ball = find_ball(points_cam, rgb, self.radius_m)
            return ball.p_cam, ball.confidence
        from .blob import find_blob

        blob = find_blob(points_cam, rgb)
        return blob.p_cam, blob.confidence
