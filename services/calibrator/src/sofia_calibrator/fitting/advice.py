"""Advice a calibration gives about itself: which removal would meet the lab's criterion, noise far
above what the camera explains, too few or too similar poses."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from . import correction as cc
from . import diagnostics as dg
from . import so3
from .influence import influence

if TYPE_CHECKING:
    from .fit import Fit, Problem, Selection

NOISE_WARN_RATIO = 3.0  # fitted noise this many times the camera model's is worth a warning
DISTINCT_DEG = 5.0  # flange orientations closer than this count as one
FEW_ORIENTATIONS = 3
FEW_POSES = 5  # up to 5 poses the closed form is not over-determined: advise more
ADD_POSES = 4


def _mapping_jacobian(prob: Problem, sel: Selection, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mapped blobs (m, 3) base frame of samples ``idx`` and their derivative (m, 3, p) by the
    parameters (theta, t, p_base, beta) of the selection's solution."""
    sol = sel.solution
    p, T = prob.p_cam[idx], prob.T_base_flange[idx]
    G = cc.columns(sol.model, p)
    c = p + G @ sol.beta if len(sol.beta) else p
    R_base_cam = T[:, :3, :3] @ sol.R
    mapped = np.einsum("nij,nj->ni", R_base_cam, c) + T[:, :3, :3] @ sol.t + T[:, :3, 3]
    M = np.zeros((len(idx), 3, 9 + len(sol.beta)))
    M[:, :, :3] = -R_base_cam @ so3.hat(c)
    M[:, :, 3:6] = T[:, :3, :3]
    M[:, :, 9:] = R_base_cam @ G
    return mapped, M


def criterion_advice(prob: Problem, sel: Selection, idx: np.ndarray, max_remove: int) -> list[int]:
    """The fewest samples (greedy, at most ``max_remove``) whose removal makes the fit meet the
    lab's criterion, or [] when that is not enough. Candidates (the samples at an axis' extremes
    and the four agreeing least) are ranked by the linearised leave-one-out fit (hat matrix); the
    chosen removal is confirmed by a refit."""
    removed: list[int] = []
    for _ in range(max_remove):
        if 3 * len(idx) - sel.solution.JtJ.shape[0] <= 3:
            break
        mapped, M = _mapping_jacobian(prob, sel, idx)
        inf = influence(sel.solution)
        # candidates: the samples at the extremes of an axis, and those agreeing least with the rest
        loo = np.linalg.norm(inf.loo_whitened, axis=1)
        cand = np.unique(np.r_[mapped.argmax(axis=0), mapped.argmin(axis=0), np.argsort(loo)[-4:]])
        m = len(idx)
        moved = mapped[None] + (M.reshape(3 * m, -1) @ inf.shift[cand].T).T.reshape(len(cand), m, 3)
        moved[np.arange(len(cand)), cand] = np.nan  # without sample i
        score = np.max(np.nanmax(moved, axis=1) - np.nanmin(moved, axis=1), axis=1)
        k = int(cand[int(np.argmin(score))])
        removed.append(int(idx[k]))
        idx = np.delete(idx, k)
        sel = prob.select(idx, start=sel.solution)
        if prob.explain(idx, sel).passes:
            return removed
    return []


def noise_warning(fit: Fit) -> list[str]:
    """A warning when the fitted noise is far above what the camera model explains."""
    if fit.noise_scale <= NOISE_WARN_RATIO or 3 * len(fit.samples) - fit.covariance.shape[0] < 3:
        return []
    return [
        f"fitted noise {fit.noise_mm:.2f} mm per axis is {fit.noise_scale:.1f}x what the camera explains "
        f"({fit.camera_noise_mm:.2f} mm): check the robot's positioning (T_base_flange must be "
        "panda_link0 -> panda_link8, not O_T_EE), the time sync of blob and pose, and the blob extraction"
    ]


def distinct_orientations(T_base_flange: np.ndarray, enough: int | None = None) -> int:
    """How many flange orientations differ by more than ``DISTINCT_DEG`` from each other (greedy),
    counting up to ``enough`` at most (all when None).

    The angle between R_i and R_j from trace(R_i^T R_j) = 1 + 2 cos(angle), all pairs at once."""
    F = T_base_flange[:, :3, :3].reshape(-1, 9)
    close = (F @ F.T - 1.0) / 2.0 > np.cos(np.radians(DISTINCT_DEG))
    covered = np.zeros(len(F), dtype=bool)
    count = 0
    for i in range(len(F)):
        if not covered[i]:
            count += 1
            if count == enough:
                break
            covered |= close[i]
    return count


def redundancy_warning(fit: Fit, T_base_flange: np.ndarray) -> list[str]:
    """'Add poses' advice for sets with too few poses or flange orientations, with the expected
    1-sigma after adding ``ADD_POSES`` poses as varied as the present ones."""
    m = len(fit.samples)
    dof = 3 * m - fit.covariance.shape[0]
    if dof <= 0:
        return [
            f"{m} samples leave no redundancy: the uncertainty is the modelled noise, not measured; add "
            "poses tilted 15-30 deg about different axes"
        ]
    k = distinct_orientations(T_base_flange[fit.samples], None if m <= FEW_POSES else FEW_ORIENTATIONS + 1)
    if m > FEW_POSES and k > FEW_ORIENTATIONS:
        return []
    f = np.sqrt(max(k, 1) / (max(k, 1) + ADD_POSES))
    return [
        f"only {m} poses with {k} distinct flange orientations: the transform rests on few poses "
        f"(1-sigma {dg.fmt3(fit.std_translation_mm)} mm, {dg.fmt3(fit.std_rotation_deg, 2)} deg); add "
        f"poses tilted 15-30 deg about different axes: with {ADD_POSES} more as varied as these, about "
        f"{dg.fmt3(fit.std_translation_mm * f)} mm, {dg.fmt3(fit.std_rotation_deg * f, 2)} deg"
    ]
