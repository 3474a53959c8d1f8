"""Point-based hand-eye solver: closed-form linear start, then Levenberg-Marquardt on SE(3) x R^3.

Model: a blob fixed at ``p_base`` is seen at ``p_cam_i`` while the flange is at ``T_base_flange_i``:

    p_cam_i = R^T (R_i^T (p_base - t_i) - t) + noise_i,      T_flange_cam = [R t; 0 1]

The residual is taken in the camera frame, where the measurement noise lives (per-axis sigma, depth
noise growing with z^2), so the whitened least-squares solution is the maximum-likelihood one.
Its norm equals the distance of the mapped blob ``T_base_flange_i T_flange_cam p_cam_i`` to p_base.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from . import correction, so3
from . import fit_kernels as fk
from .kernels import c_array as _c

LOSSES = ("linear", "huber", "cauchy")
# Up to 5 samples the 15-unknown linear start is not over-determined; more starts are tried.
MIN_LINEAR_SAMPLES = 5
MAX_OFFSET_M = 0.5  # a camera further than this from the flange is a wrong minimum
MULTI_STARTS = 6  # cube rotations refined, the best by their closed-form cost
IMPLAUSIBLE_RMS_M = 0.01  # RMS residual per axis above which more starts are tried, metres


@dataclass
class Solution:
    """A solution of the solver. R, t: T_flange_cam blocks; p_base: blob, base frame, metres."""

    R: np.ndarray  # (3, 3) R_flange_cam
    t: np.ndarray  # (3,) t_flange_cam, metres
    p_base: np.ndarray  # (3,) blob in the base frame, metres
    cost: float  # sum of robust(squared whitened residual norms)
    n_iter: int
    JtJ: np.ndarray  # (9 + k, 9 + k) Gauss-Newton information matrix, params (theta, t, p_base, beta)
    errors: np.ndarray  # (n, 3) predicted minus corrected measured blob, camera frame, metres
    weights: np.ndarray  # (n,) robust weights of the samples at the solution (1 = full weight)
    model: str = "rigid"  # camera-correction model (see :mod:`sofia_calibrator.fitting.correction`)
    beta: np.ndarray = field(default_factory=lambda: np.zeros(0))  # (k,) correction unknowns
    J: np.ndarray | None = None  # (3 n, 9 + k) whitened Jacobian at the solution
    whitened: np.ndarray | None = None  # (n, 3) whitened residuals (errors / sigma)
    prior_info: float = 0.0  # information of a prior on beta[0], included in JtJ (:mod:`.prior`)

    @property
    def T_flange_cam(self) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = self.R, self.t
        return T


def linear_init(
    p_cam: np.ndarray, R_base_flange: np.ndarray, t_base_flange: np.ndarray, w: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closed-form start: R_i (R p_cam_i + t) - p_base = -t_i is linear in (vec R, t, p_base).

    p_cam: (n, 3) camera frame; R_base_flange: (n, 3, 3); t_base_flange: (n, 3) base frame, metres;
    w: (n,) sample weights. The 15-unknown least-squares solution (normal equations of the
    column-equilibrated system when n >= 10, else or when rank-deficient an SVD least squares) has
    its R projected onto SO(3) (t and p_base are kept: the first Gauss-Newton step re-solves them
    with R). Returns (R (3, 3), t (3,), p_base (3,)).
    """
    A, b, x, solved = fk.linear_system(_c(p_cam), _c(R_base_flange), _c(t_base_flange), _c(w))
    if not solved:  # not over-determined enough, or rank-deficient
        x = np.linalg.lstsq(A, b, rcond=None)[0]
    return so3.project(x[:9].reshape(3, 3)), x[9:12], x[12:]


def refine(
    p_cam: np.ndarray,
    R_base_flange: np.ndarray,
    t_base_flange: np.ndarray,
    sigma: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    p_base: np.ndarray,
    loss: str = "linear",
    loss_scale: float = 3.0,
    max_iter: int = 100,
    tol: float = 1e-9,
    model: str = "rigid",
    beta: np.ndarray | None = None,
) -> Solution:
    """Levenberg-Marquardt from (R, t, p_base, beta), R updated on the right: R exp([dtheta]x).

    Residual (camera frame) f_i = R^T (R_i^T (p_base - t_i) - t) - (p_cam_i + G_i beta) =: u_i - c_i
    with df/dtheta = [u_i]x, df/dt = -R^T, df/dp_base = R^T R_i^T, df/dbeta = -G_i (the camera
    correction of ``model``, :mod:`sofia_calibrator.fitting.correction`). sigma: (n, 3) per-axis camera-frame
    noise, metres (whitening); loss: "linear", "huber" or "cauchy" with ``loss_scale`` in sigma
    units (robust loss by iteratively reweighting samples). The iteration runs compiled
    (:func:`sofia_calibrator.fitting.fit_kernels.levenberg_marquardt`).
    """
    G = correction.columns(model, p_cam)
    k = G.shape[2]
    beta = np.zeros(k) if beta is None or len(beta) != k else _c(beta)
    R, t, p_base, beta, cost, it, H, J, r, w = fk.levenberg_marquardt(
        _c(p_cam), _c(R_base_flange), _c(t_base_flange), _c(sigma), G, _c(R), _c(t), _c(p_base), beta,
        fk.LOSS_CODES[loss], float(loss_scale), int(max_iter), float(tol),
    )  # fmt: skip
    return Solution(R, t, p_base, cost, it, H, r * sigma, w, model, beta, J, r)


def plausible(sol: Solution) -> bool:
    """A camera within ``MAX_OFFSET_M`` of the flange with an RMS residual per axis below
    ``IMPLAUSIBLE_RMS_M`` (else a wrong minimum is suspected)."""
    ms = float(np.vdot(sol.errors, sol.errors)) / sol.errors.size
    return bool(float(sol.t @ sol.t) < MAX_OFFSET_M**2 and ms < IMPLAUSIBLE_RMS_M**2)


def solve(
    p_cam: np.ndarray,
    T_base_flange: np.ndarray,
    sigma: np.ndarray | None = None,
    T_flange_cam_guess: np.ndarray | None = None,
    loss: str = "linear",
    loss_scale: float = 3.0,
    model: str = "rigid",
) -> Solution:
    """Solve for T_flange_cam and p_base; inputs are trusted (see :func:`calibrate` for validation).

    p_cam: (n, 3) camera frame, metres; T_base_flange: (n, 4, 4); sigma: (n, 3) metres or None
    (1 mm). Starts: the linear closed form, plus the guess when given (one more start, never the
    only one), plus the ``MULTI_STARTS`` best of the 24 cube rotations when the linear system is not over-determined
    (n <= 5) or the best solution is implausible (:func:`plausible`). The lowest cost of the
    plausible solutions wins.
    """
    R_fl, t_fl = _c(T_base_flange[:, :3, :3]), _c(T_base_flange[:, :3, 3])
    p_cam = _c(p_cam)
    sigma = np.full_like(p_cam, 1e-3) if sigma is None else _c(sigma)

    def from_start(R0: np.ndarray, t0: np.ndarray, p0: np.ndarray | None = None) -> Solution:
        if p0 is None:  # the mean of the blob mapped into the base frame through (R0, t0)
            p0 = np.mean(np.einsum("nij,nj->ni", R_fl, p_cam @ R0.T + t0) + t_fl, axis=0)
        return refine(p_cam, R_fl, t_fl, sigma, R0, t0, p0, loss, loss_scale, model=model)

    R, t, p_base = linear_init(p_cam, R_fl, t_fl, (3.0 / sigma.sum(axis=1)) ** 2)  # 1 / mean sigma^2
    sols = [from_start(R, t, p_base)]
    if T_flange_cam_guess is not None:
        sols.append(from_start(T_flange_cam_guess[:3, :3], T_flange_cam_guess[:3, 3]))
    ok = [plausible(s) for s in sols]
    if len(p_cam) <= MIN_LINEAR_SAMPLES or not any(ok):
        best = np.argsort(_rotation_only_costs(p_cam, R_fl, t_fl, _CUBE))[:MULTI_STARTS]
        more = [from_start(R0, np.zeros(3)) for R0 in _CUBE[best]]
        sols, ok = sols + more, ok + [plausible(s) for s in more]
    return sols[min(range(len(sols)), key=lambda i: (not ok[i], sols[i].cost))]  # a plausible camera first


def _rotation_only_costs(
    p_cam: np.ndarray, R_base_flange: np.ndarray, t_base_flange: np.ndarray, Rs: np.ndarray
) -> np.ndarray:
    """(m,) least-squares costs of fixed rotations Rs (m, 3, 3) = R_flange_cam: R_i (R p_i + t) +
    t_i = p_base is linear in (t, p_base), with the same matrix for every R (one pseudo-inverse)."""
    n = len(p_cam)
    A = np.zeros((n, 3, 6))
    A[:, :, :3] = R_base_flange
    A[:, :, 3:] = -np.eye(3)
    A2 = A.reshape(-1, 6)
    B = -(t_base_flange[None] + np.einsum("nij,mkj,nk->mni", R_base_flange, Rs, p_cam))  # (m, n, 3)
    B2 = B.reshape(len(Rs), -1)
    resid = B2 - (B2 @ np.linalg.pinv(A2).T) @ A2.T
    return np.asarray(np.einsum("mi,mi->m", resid, resid))


# (24, 3, 3) the rotations of the cube (SciPy's octahedral group), entries exactly 0 and +-1
_CUBE = Rotation.create_group("O").as_matrix().round()
