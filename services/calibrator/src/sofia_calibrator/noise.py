"""Noise model of a blob position measured by a D435-like RGB-D camera.

Depth noise grows with depth squared (stereo disparity error), lateral noise linearly with depth
(sub-pixel error of the blob centre). Both are expressed per camera-frame axis.
"""

from __future__ import annotations

import numpy as np

# Nominal D435 values: 0.08 px sub-pixel disparity, 383 px focal length, 50 mm baseline
# -> sigma_z = 0.0042 z^2 (1 mm at 0.5 m); blob centre 0.3 px at 615 px focal length.
DEPTH_COEFF_PER_M = 0.0042
LATERAL_COEFF = 0.3 / 615.0
FLOOR_M = 1e-4


def camera_sigma(
    p_cam: np.ndarray,
    depth_coeff_per_m: float = DEPTH_COEFF_PER_M,
    lateral_coeff: float = LATERAL_COEFF,
) -> np.ndarray:
    """1-sigma noise of blob positions per camera axis.

    p_cam: (n, 3) float, camera optical frame (z forward), metres.
    Returns (n, 3) float metres: (lateral, lateral, depth) = (c z, c z, k z^2), floored at 0.1 mm.
    """
    z = np.abs(p_cam[:, 2])
    lateral = np.maximum(lateral_coeff * z, FLOOR_M)
    depth = np.maximum(depth_coeff_per_m * z**2, FLOOR_M)
    return np.stack([lateral, lateral, depth], axis=1)


def sample_noise(p_cam: np.ndarray, rng: np.random.Generator, scale: float = 1.0) -> np.ndarray:
    """(n, 3) Gaussian noise drawn from :func:`camera_sigma` (times ``scale``), metres."""
    return rng.standard_normal(p_cam.shape) * camera_sigma(p_cam) * scale
