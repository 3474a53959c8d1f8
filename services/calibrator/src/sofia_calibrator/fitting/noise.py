"""Noise model of a blob position measured by a D435-like RGB-D camera, per camera-frame axis:
depth noise grows with depth squared (stereo disparity), lateral noise linearly with depth
(sub-pixel error of the blob centre). :class:`NoiseModel` adds the robot's and the blob
extraction's roughly isotropic errors as one component estimated from the residuals.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .kernels import c_array, jit

# Nominal D435 values: 0.08 px sub-pixel disparity, 383 px focal length, 50 mm baseline
# -> sigma_z = 0.0042 z^2 (1 mm at 0.5 m); blob centre 0.3 px at 615 px focal length.
DEPTH_COEFF_PER_M = 0.0042
LATERAL_COEFF = 0.3 / 615.0
FLOOR_M = 1e-4
ISOTROPIC_PRIOR_M = 1e-3  # starting value of the isotropic component before it is estimated


def camera_sigma(p_cam: np.ndarray) -> np.ndarray:
    """1-sigma noise of blob positions per camera axis.

    p_cam: (n, 3) float, camera optical frame (z forward), metres.
    Returns (n, 3) float metres: (lateral, lateral, depth) = (c z, c z, k z^2), floored at 0.1 mm.
    """
    z = np.abs(np.asarray(p_cam, dtype=np.float64)[:, 2])
    lateral = np.maximum(LATERAL_COEFF * z, FLOOR_M)
    return np.stack((lateral, lateral, np.maximum(DEPTH_COEFF_PER_M * z * z, FLOOR_M)), axis=1)


def sample_noise(p_cam: np.ndarray, rng: np.random.Generator, scale: float = 1.0) -> np.ndarray:
    """(n, 3) Gaussian noise drawn from :func:`camera_sigma` (times ``scale``), metres."""
    return rng.standard_normal(p_cam.shape) * camera_sigma(p_cam) * scale


def isotropic_component(errors: np.ndarray, camera: np.ndarray, dof: float, iterations: int = 30) -> float:
    """The isotropic noise s0 (metres) that, added to the camera's own noise, explains the residuals.

    errors: (n, 3) residuals, camera frame, metres; camera: (n, 3) the camera model's 1-sigma.
    Solves chi2(v) = sum e^2 / (v + c^2) = dof for v = s0^2 >= 0 (the residual chi-square equals
    its expectation, a REML-type moment equation) by Newton's method on 1 / chi2(v), which is
    concave and increasing (exactly linear when the camera term is negligible): from v = 0 the
    steps approach the root from below, monotonically. Returns 0 when the camera model alone
    explains the residuals, and NaN when ``dof <= 0``.
    """
    if dof <= 0:
        return float("nan")
    e, c = (c_array(x).ravel() for x in (errors, camera))
    return math.sqrt(_isotropic_variance(e, c, float(dof), iterations))


@jit
def _isotropic_variance(e, c, dof, iterations):  # type: ignore[no-untyped-def]
    """v = s0^2 of :func:`isotropic_component`, e and c (3 n,) raveled errors and camera sigma."""
    v = 0.0
    for _ in range(iterations):
        chi2, slope = 0.0, 0.0
        for i in range(e.size):
            w = 1.0 / (v + c[i] * c[i])
            chi2 += e[i] * e[i] * w
            slope += e[i] * e[i] * w * w
        if chi2 <= dof * (1.0 + 1e-9):
            break
        v += (chi2 - dof) * chi2 / (dof * slope)
    return v


@dataclass(frozen=True)
class NoiseModel:
    """Per-sample, per-axis 1-sigma of the blob position, with one level estimated from the data.

    base: (n, 3) metres, the known part (the camera model, or the user's sigma). ``additive``:
    sigma^2 = level^2 + base^2 (level: an isotropic component in metres: robot positioning, blob
    extraction); else sigma = level * base (level: a factor on the user's noise model).
    """

    base: np.ndarray
    additive: bool
    level: float

    def sigma(self, idx: np.ndarray | None = None) -> np.ndarray:
        """(m, 3) metres for the samples ``idx`` (all when None)."""
        b = self.base if idx is None else self.base[idx]
        return np.sqrt(self.level**2 + b**2) if self.additive else self.level * b

    def estimated(self, errors: np.ndarray, idx: np.ndarray, dof: int) -> NoiseModel:
        """The model with its level estimated from (m, 3) residuals of the samples ``idx`` (metres)
        of a fit with ``dof`` degrees of freedom; unchanged when dof <= 0."""
        if dof <= 0:
            return self
        if self.additive:
            level = isotropic_component(errors, self.base[idx], dof)
        else:
            level = float(np.sqrt(np.sum((errors / self.base[idx]) ** 2) / dof))
        return NoiseModel(self.base, self.additive, max(level, 0.0))


def rms_mm(sigma: np.ndarray) -> float:
    """RMS 1-sigma per axis of (m, 3) metres, in mm."""
    return 1e3 * float(np.sqrt(np.vdot(sigma, sigma) / sigma.size))
