"""The calibration point the live service takes from each camera cloud (``serve --from-clouds``):
the blob on the sheet (:func:`sofia_calibrator.blob.find_blob`) or a ball
(:func:`sofia_calibrator.targets.ball.find_ball`), with its confidence. A ball of unknown radius:
its last ``MAX_VIEWS`` views' segments are kept and each solve refits their centres with one shared
radius (:func:`~sofia_calibrator.targets.sphere_shared.fit_shared`; synthetic 25 mm balls, 12 sets
of 10 views: centre error 0.22 mm RMS per view, 0.10 mm shared)."""

from __future__ import annotations

import logging
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np
from sofia_schemas.cloud import PointCloud2

from .errors import InputMismatch
from .targets.ball import CLOUD_TARGETS, find_target
from .targets.sphere_shared import MAX_POINTS_PER_VIEW, fit_shared

log = logging.getLogger(__name__)
# Ball views kept for the shared radius (the latest; older samples keep their own fit's centre).
# The refit costs each solve about 30 ms per view (0.95 s for 30 views of 1500 points, load 4).
MAX_VIEWS = 30


@dataclass
class CloudTarget:
    """``kind``: blob or ball; ``radius_m``: the ball's radius (metres; None: fitted per view)."""

    kind: str = "blob"
    radius_m: float | None = None
    # stamp_ns -> the view's ball segment (inliers (k, 3) camera frame m, centre (3,), radius m)
    segments: OrderedDict[int, tuple[np.ndarray, np.ndarray, float]] = field(default_factory=OrderedDict)

    def __post_init__(self) -> None:
        if self.kind not in CLOUD_TARGETS:
            raise InputMismatch(f"cloud target must be one of {list(CLOUD_TARGETS)}, got {self.kind!r}")

    def find(self, points_cam: np.ndarray, rgb: np.ndarray, stamp_ns: int = 0) -> tuple[np.ndarray, float]:
        """(p_cam (3,) camera optical frame m, confidence 0..1) of the target in an organized cloud
        points_cam (H, W, 3) with colours rgb (H, W, 3) uint8 stamped ``stamp_ns``; raises
        CalibrationError when absent."""
        p_cam, confidence, segment = find_target(self.kind, points_cam, rgb, self.radius_m)
        if segment is not None and self.radius_m is None:  # a ball's view, for the shared radius
            pts, centre, radius = segment
            self.segments[stamp_ns] = (pts[:: max(1, -(-len(pts) // MAX_POINTS_PER_VIEW))], centre, radius)
            while len(self.segments) > MAX_VIEWS:
                self.segments.popitem(last=False)
        return p_cam, confidence

    def find_in(self, cloud: PointCloud2) -> tuple[np.ndarray, float]:
        """:meth:`find` in an organized camera cloud message with an rgb field."""
        rgb = cloud.rgb()
        if rgb is None:
            raise InputMismatch("camera cloud has no rgb field")
        shape = (cloud.height, cloud.width, 3)
        return self.find(cloud.xyz().reshape(shape), rgb.reshape(shape), cloud.stamp_ns)

    def shared_centres(self, stamps_ns: list[int]) -> dict[int, np.ndarray]:
        """stamp_ns -> (3,) ball centre (camera optical frame, metres) of the samples ``stamps_ns``
        whose view is kept, refitted with one radius shared by them; empty below 2 such views or
        with a known radius."""
        kept = [s for s in stamps_ns if s in self.segments]
        if self.radius_m is not None or len(kept) < 2:
            return {}
        spheres = fit_shared([self.segments[s] for s in kept])
        log.info("ball radius %.2f mm shared by %d views", 1e3 * spheres[0].radius_m, len(kept))
        return {s: sph.p_cam for s, sph in zip(kept, spheres, strict=True)}
