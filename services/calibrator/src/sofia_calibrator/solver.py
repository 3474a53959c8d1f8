"""Point-based hand-eye solver: closed-form linear start, then Levenberg-Marquardt on SE(3) x R^3.

Model: a blob fixed at ``p_base`` is seen at ``p_cam_i`` while the flange is at ``T_base_flange_i``:

    p_cam_i = R^T (R_i^T (p_base - t_i) - t) + noise_i,      T_flange_cam = [R t; 0 1]

The residual is taken in the camera frame, where the measurement noise lives (per-axis sigma, depth
noise growing with z^2), so the whitened least-squares solution is the maximum-likelihood one.
Its norm equals the distance of the mapped blob ``T_base_flange_i T_flange_cam p_cam_i`` to p_base.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import so3

LOSSES = ("linear", "huber", "cauchy")
# Below 5 samples the 15-unknown linear start is underdetermined; more starts are tried.
MIN_LINEAR_SAMPLES = 5


@dataclass
class Solution:
    """A solution of the solver. R, t: T_flange_cam blocks; p_base: blob, base frame, metres."""

    R: np.ndarray  # (3, 3) R_flange_cam
    t: np.ndarray  # (3,) t_flange_cam, metres
    p_base: np.ndarray  # (3,) blob in the base frame, metres
    cost: float  # sum of robust(squared whitened residual norms)
    n_iter: int
    JtJ: np.ndarray  # (9, 9) Gauss-Newton information matrix (unit weights), params (theta, t, p_base)
    errors: np.ndarray  # (n, 3) predicted minus measured blob, camera frame, metres
    weights: np.ndarray  # (n,) robust weights of the samples at the solution (1 = full weight)

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
    w: (n,) sample weights. The 15-unknown least-squares solution's R is projected onto SO(3),
    then t and p_base are solved again with R fixed. Returns (R (3, 3), t (3,), p_base (3,)).
    """
    n = len(p_cam)
    A = np.zeros((n, 3, 15))
    A[:, :, :9] = np.einsum("nka,nb->nkab", R_base_flange, p_cam).reshape(n, 3, 9)
    A[:, :, 9:12] = R_base_flange
    A[:, :, 12:] = -np.eye(3)
    b = -t_base_flange
    sw = np.sqrt(w)[:, None]
    x = np.linalg.lstsq((A * sw[:, :, None]).reshape(-1, 15), (b * sw).ravel(), rcond=None)[0]
    R = so3.project(x[:9].reshape(3, 3))
    A6 = A[:, :, 9:]
    b6 = b - np.einsum("nij,nj->ni", R_base_flange, p_cam @ R.T)
    y = np.linalg.lstsq((A6 * sw[:, :, None]).reshape(-1, 6), (b6 * sw).ravel(), rcond=None)[0]
    return R, y[:3], y[3:]


def _errors(
    R: np.ndarray, t: np.ndarray, p_base: np.ndarray, p_cam: np.ndarray, Rt_fl: np.ndarray, t_fl: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(predicted - measured (n, 3), predicted p_cam u (n, 3)), camera frame."""
    q = np.einsum("nij,nj->ni", Rt_fl, p_base - t_fl)  # blob in the flange frame at each pose
    u = (q - t) @ R
    return u - p_cam, u


def _robust(s: np.ndarray, loss: str, c: float) -> tuple[np.ndarray, np.ndarray]:
    """rho(s) and rho'(s) of squared whitened norms s (n,), with rho'(0) = 1."""
    if loss == "huber":
        r = np.sqrt(s)
        inside = r <= c
        return np.where(inside, s, 2 * c * r - c * c), np.where(inside, 1.0, c / np.maximum(r, 1e-300))
    if loss == "cauchy":
        return c * c * np.log1p(s / (c * c)), 1.0 / (1.0 + s / (c * c))
    return s, np.ones_like(s)


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
    tol: float = 1e-10,
) -> Solution:
    """Levenberg-Marquardt from (R, t, p_base), R updated on the right: R exp([dtheta]x).

    sigma: (n, 3) per-axis camera-frame noise, metres (whitening); loss: "linear", "huber" or
    "cauchy" with ``loss_scale`` in sigma units (robust loss by iteratively reweighting samples).
    """
    Rt_fl = np.swapaxes(R_base_flange, 1, 2)
    inv_sigma = 1.0 / sigma
    n = len(p_cam)

    def evaluate(R: np.ndarray, t: np.ndarray, p_base: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        f, u = _errors(R, t, p_base, p_cam, Rt_fl, t_base_flange)
        e = f * inv_sigma
        rho, w = _robust(np.einsum("ni,ni->n", e, e), loss, loss_scale)
        return float(rho.sum()), np.concatenate([f, u], axis=1), w

    def jacobian(R: np.ndarray, u: np.ndarray) -> np.ndarray:
        J = np.empty((n, 3, 9))
        J[:, :, :3] = so3.hat(u)
        J[:, :, 3:6] = -R.T
        J[:, :, 6:] = np.einsum("ji,njk->nik", R, Rt_fl)
        return J

    cost, fu, w = evaluate(R, t, p_base)
    lam = -1.0
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 - it is reported
        f, u = fu[:, :3], fu[:, 3:]
        J = jacobian(R, u) * inv_sigma[:, :, None]
        e = f * inv_sigma
        Jw = J * w[:, None, None]
        H = np.einsum("nki,nkj->ij", Jw, J)
        g = np.einsum("nki,nk->i", Jw, e)
        if lam < 0:
            lam = 1e-6
        improved = False
        while lam < 1e16:
            dx = np.linalg.solve(H + lam * np.diag(np.diag(H) + 1e-12), -g)
            R_new = R @ so3.exp(dx[:3])
            t_new, p_new = t + dx[3:6], p_base + dx[6:]
            cost_new, fu_new, w_new = evaluate(R_new, t_new, p_new)
            if cost_new <= cost:
                improved = True
                break
            lam = max(lam, 1e-9) * 10.0
        if not improved:
            break
        done = cost - cost_new <= tol * max(cost, 1e-300) or float(dx @ dx) < 1e-24
        R, t, p_base, cost, fu, w = R_new, t_new, p_new, cost_new, fu_new, w_new
        lam = max(lam / 10.0, 1e-12)
        if done:
            break
    J = jacobian(R, fu[:, 3:]) * inv_sigma[:, :, None]
    JtJ = np.einsum("nki,nkj->ij", J, J)
    return Solution(so3.project(R), t, p_base, cost, it, JtJ, fu[:, :3], w)


def solve(
    p_cam: np.ndarray,
    T_base_flange: np.ndarray,
    sigma: np.ndarray | None = None,
    T_flange_cam_guess: np.ndarray | None = None,
    loss: str = "linear",
    loss_scale: float = 3.0,
) -> Solution:
    """Solve for T_flange_cam and p_base; inputs are trusted (see :func:`calibrate` for validation).

    p_cam: (n, 3) camera frame, metres; T_base_flange: (n, 4, 4); sigma: (n, 3) metres or None (unit).
    Without a guess the linear closed form starts the refinement; with one, p_base starts at the
    mean of the blob mapped through the guess.
    """
    R_fl, t_fl = T_base_flange[:, :3, :3], T_base_flange[:, :3, 3]
    if sigma is None:
        sigma = np.ones_like(p_cam)
    if T_flange_cam_guess is not None:
        R, t = T_flange_cam_guess[:3, :3], T_flange_cam_guess[:3, 3]
        return refine(p_cam, R_fl, t_fl, sigma, R, t, start_target(p_cam, R_fl, t_fl, R, t), loss, loss_scale)
    R, t, p_base = linear_init(p_cam, R_fl, t_fl, 1.0 / np.mean(sigma, axis=1) ** 2)
    best = refine(p_cam, R_fl, t_fl, sigma, R, t, p_base, loss, loss_scale)
    if len(p_cam) < MIN_LINEAR_SAMPLES:  # the linear system is underdetermined: add starts
        for R0 in cube_rotations():
            z = np.zeros(3)
            sol = refine(
                p_cam, R_fl, t_fl, sigma, R0, z, start_target(p_cam, R_fl, t_fl, R0, z), loss, loss_scale
            )
            if sol.cost < best.cost:
                best = sol
    return best


def start_target(
    p_cam: np.ndarray, R_base_flange: np.ndarray, t_base_flange: np.ndarray, R: np.ndarray, t: np.ndarray
) -> np.ndarray:
    """(3,) mean of the blob mapped into the base frame through (R, t) = T_flange_cam."""
    return np.asarray(
        np.mean(np.einsum("nij,nj->ni", R_base_flange, p_cam @ R.T + t) + t_base_flange, axis=0)
    )


def cube_rotations() -> np.ndarray:
    """(24, 3, 3) the rotations of the cube: well-spread starting rotations."""
    perms = [(0, 1, 2), (1, 2, 0), (2, 0, 1), (1, 0, 2), (0, 2, 1), (2, 1, 0)]
    out = []
    for perm in perms:
        for signs in np.array(np.meshgrid([1, -1], [1, -1], [1, -1])).T.reshape(-1, 3):
            M = np.eye(3)[list(perm)] * signs[:, None]
            if np.linalg.det(M) > 0:
                out.append(M)
    return np.array(out)
