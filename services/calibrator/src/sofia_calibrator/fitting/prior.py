"""A depth scale known from an earlier calibration of the same camera, used as a Gaussian prior.

A D435's depth-scale error belongs to the camera, not to the mount; on a small set the data alone
cannot always tell a 5 % error from noise (measured in ``docs/how-to/calibration-targets.md``).
The depth-scale model is then fitted with one more observation, ``beta ~ N(scale - 1, sigma^2 +
drift^2)``: the data's optimum moved by one Gauss-Newton step of the prior (exact, the model is
linear in beta), refined with beta held; its information matrix holds the prior, so the
covariance, leave-one-out and outlier tests count it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from ..errors import InputMismatch
from . import correction as cc
from . import so3
from .kernels import inverse
from .solver import Solution, refine

# How far a camera's depth scale may have moved since the earlier calibration (temperature, an
# on-chip recalibration), 1-sigma, added in quadrature to the earlier calibration's own 1-sigma.
DRIFT = 0.005
# A data scale further than this many combined sigmas from the prior is reported as a change.
CONFLICT_SIGMAS = 3.0


@dataclass(frozen=True)
class ScalePrior:
    """Depth scale (1 = exact) and its 1-sigma from an earlier calibration of the same camera."""

    scale: float
    sigma: float
    drift: float = DRIFT

    def __post_init__(self) -> None:
        if not (math.isfinite(self.scale) and 0.5 < self.scale < 1.5):
            raise InputMismatch(f"the prior depth scale must be within (0.5, 1.5), got {self.scale}")
        if not (
            math.isfinite(self.sigma) and self.sigma >= 0 and math.isfinite(self.drift) and self.drift >= 0
        ):
            raise InputMismatch(
                f"the prior's sigma and drift must be finite and >= 0, got {self.sigma}, {self.drift}"
            )
        if self.width == 0.0:
            raise InputMismatch("the prior's sigma and drift cannot both be 0")

    @property
    def width(self) -> float:
        """1-sigma of the scale now: the earlier sigma and the drift in quadrature."""
        return math.hypot(self.sigma, self.drift)

    def describe(self) -> str:
        return f"{self.scale:.4f} +- {self.width:.4f} from an earlier calibration"


def fit_with_prior(
    data: Solution,
    prior: ScalePrior,
    p_cam: np.ndarray,
    T_base_flange: np.ndarray,
    sigma: np.ndarray,
    loss: str,
    loss_scale: float,
) -> tuple[Solution | None, str]:
    """The depth-scale solution of ``data`` (its data-only optimum, model depth_scale) under the
    prior, and one line saying how data and prior agree. No solution (the choice is then made as
    without a prior) when the data's scale lies more than ``CONFLICT_SIGMAS`` from the prior (the
    camera's depth changed), or when the scale they give together does not differ from 1 at
    ``correction.MODEL_ALPHA`` (an exact camera stays exact).

    p_cam: (m, 3) camera frame, metres; T_base_flange: (m, 4, 4); sigma: (m, 3) the noise ``data``
    was whitened with, metres. Returns a Solution whose ``JtJ`` holds the prior's information.
    """
    assert data.model == "depth_scale" and data.J is not None
    mu = prior.scale - 1.0
    s_data, v_data = 1.0 + float(data.beta[0]), float(inverse(data.JtJ)[9, 9])
    why = f"prior {prior.describe()}, these samples alone {s_data:.4f}"
    gap = abs(s_data - prior.scale) / math.sqrt(v_data + prior.width**2)
    if gap > CONFLICT_SIGMAS:  # the camera's scale moved: it is not held to the old one
        return None, f"{why}: {gap:.1f} sigma apart, so the prior is not used (the camera's depth changed?)"
    info = 1.0 / prior.width**2
    H = data.JtJ.copy()
    H[9, 9] += info
    C = inverse(H)
    dx = -C[:, 9] * info * (data.beta[0] - mu)
    beta = data.beta + dx[9:]
    z2 = float(beta[0] ** 2 / C[9, 9])
    if z2 < chi2.isf(cc.MODEL_ALPHA, 1):
        return None, f"{why}; together {1 + beta[0]:.4f} +- {math.sqrt(C[9, 9]):.4f}, not different from 1"
    p_corr = cc.apply("depth_scale", beta, p_cam)
    held = refine(p_corr, T_base_flange[:, :3, :3], T_base_flange[:, :3, 3], sigma,
                  data.R @ so3.exp(dx[:3]), data.t + dx[3:6], data.p_base + dx[6:9], loss, loss_scale)  # fmt: skip
    assert held.J is not None
    g = cc.columns("depth_scale", p_cam).reshape(-1, 1) / -sigma.reshape(-1, 1)
    J = np.hstack([held.J, g])
    JtJ = J.T @ J
    JtJ[9, 9] += info
    sol = Solution(held.R, held.t, held.p_base, held.cost, data.n_iter + held.n_iter, JtJ, held.errors,
                   held.weights, "depth_scale", beta, J, held.whitened, info)  # fmt: skip
    return sol, f"depth_scale: {why}"
