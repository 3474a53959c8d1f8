"""A fit over a subset of the samples and what explains it (spread, dissipation, covariance)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sofia_schemas.transforms import matrix_to_quat_xyzw, rpy_from_matrix

from . import diagnostics as dg
from .solver import Solution, linear_init, refine, solve


@dataclass
class Fit:
    """One fit over a subset of the samples. ``T_flange_cam`` maps camera points into the flange frame."""

    T_flange_cam: np.ndarray  # (4, 4), metres
    p_base: np.ndarray  # (3,) blob in the base frame, metres
    samples: list[int]  # indices of the samples used
    mapped_base: np.ndarray  # (n_all, 3) every sample's blob mapped into the base frame, metres
    mapped_start: np.ndarray  # (n_all, 3) the same through the starting point (guess or linear)
    residuals_mm: np.ndarray  # (n_all,) distance of each mapped blob to p_base, mm
    spread_mm: np.ndarray  # (3,) per-axis max - min over ``samples``, mm
    dissipation_before: float  # the lab's pairwise sum over ``samples`` at the start, metres
    dissipation_after: float
    std_translation_mm: np.ndarray  # (3,) flange axes
    std_rotation_deg: np.ndarray  # (3,) about the flange axes
    covariance: np.ndarray  # (9, 9) of (theta_cam, t_flange_cam, p_base)
    noise_scale: float  # a-posteriori factor on the nominal noise model (1 = as modelled)
    n_iter: int

    @property
    def passes(self) -> bool:
        return bool(np.all(self.spread_mm < dg.LAB_SPREAD_LIMIT_MM))

    @property
    def translation(self) -> np.ndarray:
        return np.asarray(self.T_flange_cam[:3, 3])

    @property
    def quaternion_xyzw(self) -> np.ndarray:
        return np.asarray(matrix_to_quat_xyzw(self.T_flange_cam[:3, :3]))

    @property
    def rpy(self) -> np.ndarray:
        return np.asarray(rpy_from_matrix(self.T_flange_cam[:3, :3]))


@dataclass
class Problem:
    p_cam: np.ndarray
    T_base_flange: np.ndarray
    sigma: np.ndarray
    guess: np.ndarray | None
    loss: str
    loss_scale: float

    def fit(self, idx: np.ndarray, start: Solution | None = None) -> tuple[Fit, Solution]:
        p, T, s = self.p_cam[idx], self.T_base_flange[idx], self.sigma[idx]
        R_fl, t_fl = T[:, :3, :3], T[:, :3, 3]
        if start is not None:
            R0, t0 = start.R, start.t
            sol = refine(p, R_fl, t_fl, s, R0, t0, start.p_base, self.loss, self.loss_scale)
        elif self.guess is not None:
            R0, t0 = self.guess[:3, :3], self.guess[:3, 3]
            sol = solve(p, T, s, self.guess, self.loss, self.loss_scale)
        else:
            R0, t0, _ = linear_init(p, R_fl, t_fl, 1.0 / np.mean(s, axis=1) ** 2)
            sol = solve(p, T, s, None, self.loss, self.loss_scale)
        T0 = np.eye(4)
        T0[:3, :3], T0[:3, 3] = R0, t0
        return self._explain(idx, sol, T0), sol

    def _explain(self, idx: np.ndarray, sol: Solution, T_start: np.ndarray) -> Fit:
        T_fc = sol.T_flange_cam
        mapped = dg.map_to_base(self.T_base_flange, T_fc, self.p_cam)
        mapped_start = dg.map_to_base(self.T_base_flange, T_start, self.p_cam)
        dof = 3 * len(idx) - 9
        scale2 = sol.cost / dof if dof > 0 else 1.0
        cov = np.linalg.pinv(sol.JtJ) * scale2
        std_t, std_r = dg.std_from_covariance(sol.R, cov)
        return Fit(
            T_flange_cam=T_fc, p_base=sol.p_base, samples=[int(i) for i in idx], mapped_base=mapped,
            mapped_start=mapped_start, residuals_mm=1e3 * np.linalg.norm(mapped - sol.p_base, axis=1),
            spread_mm=1e3 * dg.spread(mapped[idx]), dissipation_before=dg.dissipation(mapped_start[idx]),
            dissipation_after=dg.dissipation(mapped[idx]), std_translation_mm=std_t,
            std_rotation_deg=std_r, covariance=cov, noise_scale=float(np.sqrt(scale2)), n_iter=sol.n_iter,
        )  # fmt: skip

    def whitened(self, fit: Fit) -> np.ndarray:
        """(n,) whitened residual norms of every sample under a fit."""
        d = fit.mapped_base - fit.p_base  # base frame; rotate into the camera frame to whiten
        R_base_cam = np.einsum("nij,jk->nik", self.T_base_flange[:, :3, :3], fit.T_flange_cam[:3, :3])
        e = np.einsum("nji,nj->ni", R_base_cam, d) / self.sigma
        return np.asarray(np.linalg.norm(e, axis=1))


def warm_start(fit: Fit) -> Solution:
    """A :class:`Solution` to restart refinements from a fit."""
    z = np.zeros(0)
    T = fit.T_flange_cam
    return Solution(T[:3, :3], T[:3, 3], fit.p_base, 0.0, 0, np.zeros((9, 9)), z, z)
