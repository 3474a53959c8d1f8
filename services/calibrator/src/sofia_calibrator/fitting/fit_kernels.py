"""The fit's compiled loops (numba, see :mod:`sofia_calibrator.fitting.kernels`): the closed-form start,
Levenberg-Marquardt and the Gauss-Newton steps of the correction models."""

from __future__ import annotations

import math

import numpy as np

from .kernels import cholesky_solve, inverse, jit, solve_vector
from .so3 import exp_so3

LOSS_CODES = {"linear": 0, "huber": 1, "cauchy": 2}


@jit
def linear_system(p_cam, R_base_flange, t_base_flange, w):  # type: ignore[no-untyped-def]
    """The closed-form start's system (see :func:`sofia_calibrator.fitting.solver.linear_init`): A (3 n, 15)
    and b (3 n,), rows weighted by sqrt(w); and, when 3 n >= 30, its solution through the normal
    equations of the column-equilibrated system: returns (A, b, x (15,), solved)."""
    n = p_cam.shape[0]
    A = np.zeros((3 * n, 15))
    b = np.empty(3 * n)
    for i in range(n):
        sw, rows = math.sqrt(w[i]), slice(3 * i, 3 * i + 3)
        A[rows, :9] = np.kron(R_base_flange[i], p_cam[i]) * sw  # R_i p_i^T, row-major vec R
        A[rows, 9:12] = R_base_flange[i] * sw
        A[rows, 12:] = np.eye(3) * -sw
        b[rows] = -t_base_flange[i] * sw
    x = np.zeros(15)
    if 3 * n < 30:
        return A, b, x, False
    scale = 1.0 / np.maximum(np.sqrt((A * A).sum(axis=0)), 1e-300)
    As = A * scale
    X, solved = cholesky_solve(As.T @ As, (As.T @ b).reshape((15, 1)))
    x = X[:, 0] * scale
    return A, b, x, solved


@jit
def _evaluate(R, t, p_base, beta, Rt_fl, q0, p_cam, G, inv_sigma, loss, c, u, r, w):  # type: ignore[no-untyped-def]
    """Robust cost at (R, t, p_base, beta); fills u (n, 3) predicted blob (camera frame), r (n, 3)
    whitened residual and w (n,) robust weights."""
    n, k = p_cam.shape[0], beta.shape[0]
    v = np.empty(3)
    cost = 0.0
    c2 = c * c
    for i in range(n):
        for a in range(3):
            v[a] = Rt_fl[i, a, 0] * p_base[0] + Rt_fl[i, a, 1] * p_base[1] + Rt_fl[i, a, 2] * p_base[2]
            v[a] += q0[i, a] - t[a]
        s = 0.0
        for a in range(3):
            u[i, a] = v[0] * R[0, a] + v[1] * R[1, a] + v[2] * R[2, a]
            meas = p_cam[i, a]
            for j in range(k):
                meas += G[i, a, j] * beta[j]
            r[i, a] = (u[i, a] - meas) * inv_sigma[i, a]
            s += r[i, a] * r[i, a]
        if loss == 1:  # huber
            rn = math.sqrt(s)
            if rn <= c:
                cost += s
                w[i] = 1.0
            else:
                cost += 2 * c * rn - c2
                w[i] = c / max(rn, 1e-300)
        elif loss == 2:  # cauchy
            cost += c2 * math.log1p(s / c2)
            w[i] = 1.0 / (1.0 + s / c2)
        else:
            cost += s
            w[i] = 1.0
    return cost


@jit
def _jacobian(R, u, Rt_fl, G, inv_sigma, J):  # type: ignore[no-untyped-def]
    """Fills J (3 n, 9 + k): whitened d residual / d (theta, t, p_base, beta)."""
    n, k = u.shape[0], G.shape[2]
    for i in range(n):
        for a in range(3):
            row, s = 3 * i + a, inv_sigma[i, a]
            # [u]x row a, -R^T row a, (R^T Rt_fl_i) row a
            if a == 0:
                J[row, 0], J[row, 1], J[row, 2] = 0.0, -u[i, 2] * s, u[i, 1] * s
            elif a == 1:
                J[row, 0], J[row, 1], J[row, 2] = u[i, 2] * s, 0.0, -u[i, 0] * s
            else:
                J[row, 0], J[row, 1], J[row, 2] = -u[i, 1] * s, u[i, 0] * s, 0.0
            for j in range(3):
                J[row, 3 + j] = -R[j, a] * s
                J[row, 6 + j] = (
                    R[0, a] * Rt_fl[i, 0, j] + R[1, a] * Rt_fl[i, 1, j] + R[2, a] * Rt_fl[i, 2, j]
                ) * s
            for j in range(k):
                J[row, 9 + j] = -G[i, a, j] * s


@jit
def _normal(J, w, r, H, g):  # type: ignore[no-untyped-def]
    """Fills H = J^T W J and g = J^T W r (W: each sample's weight on its three rows)."""
    Jw = J * np.repeat(w, 3).reshape((-1, 1))
    H[:] = Jw.T @ J
    g[:] = Jw.T @ r.ravel()


@jit
def levenberg_marquardt(p_cam, R_fl, t_fl, sigma, G, R, t, p_base, beta, loss, c, max_iter, tol):  # type: ignore[no-untyped-def]
    """The iteration of :func:`sofia_calibrator.fitting.solver.refine` (see there for the model); loss: a
    code of ``LOSS_CODES``. Returns (R, t, p_base, beta, cost, n_iter, JtJ, J, whitened, weights)."""
    n, k = p_cam.shape[0], G.shape[2]
    P = 9 + k
    Rt_fl = np.empty((n, 3, 3))
    q0 = np.empty((n, 3))  # q = Rt_fl p_base + q0: blob, flange frame
    for i in range(n):
        Rt_fl[i] = R_fl[i].T
        q0[i] = -(Rt_fl[i] @ t_fl[i])
    inv_sigma = 1.0 / sigma
    u, r, w = np.empty((n, 3)), np.empty((n, 3)), np.empty(n)
    u_new, r_new, w_new = np.empty((n, 3)), np.empty((n, 3)), np.empty(n)
    J, H, Hw, A = np.empty((3 * n, P)), np.empty((P, P)), np.empty((P, P)), np.empty((P, P))
    g, minus_g = np.empty(P), np.empty(P)
    t, p_base, beta = t.copy(), p_base.copy(), beta.copy()  # updated in place with their trial twins
    t_new, p_new, b_new = np.empty(3), np.empty(3), np.empty(k)
    ones = np.ones(n)
    cost = _evaluate(R, t, p_base, beta, Rt_fl, q0, p_cam, G, inv_sigma, loss, c, u, r, w)
    lam = 1e-6
    it = 0
    _jacobian(R, u, Rt_fl, G, inv_sigma, J)
    _normal(J, ones, r, H, g)
    converged = False
    while it < max_iter and not converged:
        it += 1
        if loss == 0:  # g = J^T r already
            Hw[:] = H
        else:
            _normal(J, w, r, Hw, g)
        minus_g[:] = -g
        while True:
            A[:] = Hw
            for a in range(P):
                A[a, a] += lam * (Hw[a, a] + 1e-12)
            dx = solve_vector(A, minus_g)
            decrement = -(g * dx).sum()  # Gauss-Newton decrement: the cost decrease the step promises
            if decrement <= tol * max(cost, 1e-12):
                converged = True
                break
            R_new = R @ exp_so3(dx[0], dx[1], dx[2])
            t_new[:], p_new[:], b_new[:] = t + dx[3:6], p_base + dx[6:9], beta + dx[9:]
            cost_new = _evaluate(
                R_new, t_new, p_new, b_new, Rt_fl, q0, p_cam, G, inv_sigma, loss, c, u_new, r_new, w_new
            )
            if cost_new <= cost:
                R, cost = R_new, cost_new
                t, t_new, p_base, p_new, beta, b_new = t_new, t, p_new, p_base, b_new, beta
                u, u_new, r, r_new, w, w_new = u_new, u, r_new, r, w_new, w
                lam = max(lam / 10.0, 1e-12)
                _jacobian(R, u, Rt_fl, G, inv_sigma, J)
                _normal(J, ones, r, H, g)
                break
            lam = max(lam, 1e-9) * 10.0
            if lam > 1e16:
                converged = True
                break
    return R, t, p_base, beta, cost, it, H, J, r, w


@jit
def gauss_newton_steps(J_ref, errors, sigma_ref, sigma, G, extra):  # type: ignore[no-untyped-def]
    """One Gauss-Newton step of each correction model from a reference optimum (see
    :meth:`sofia_calibrator.fitting.fit.Problem.select`). J_ref: (3 m, >= 9) whitened Jacobian under the
    noise sigma_ref (m, 3); errors: (m, 3) residuals, metres; sigma: (m, 3) the noise now; G (m, 3,
    K): the models' correction columns side by side, extra[b] of them for model b. Returns, per
    model b: chi2 (nb,), dx (nb, 9) of (theta, t, p_base), beta (nb, kmax), cov9 (nb, 9, 9) and
    beta_sigma (nb, kmax), the last two scaled by chi2 / dof. One Jacobian holds every model's
    columns: each model's normal equations are a principal block of its J^T J."""
    m, K, nb = errors.shape[0], G.shape[2], extra.shape[0]
    inv_sigma = 1.0 / sigma.reshape(3 * m)
    J = np.empty((3 * m, 9 + K))
    J[:, :9] = J_ref[:, :9] * (sigma_ref.reshape(3 * m) * inv_sigma).reshape((-1, 1))
    J[:, 9:] = G.reshape((3 * m, K)) * -inv_sigma.reshape((-1, 1))
    r = errors.reshape(3 * m) * inv_sigma
    M, g_all, rr = J.T @ J, J.T @ r, r @ r
    kmax = max(1, extra.max())
    chi2, dx = np.empty(nb), np.empty((nb, 9))
    beta, cov9, beta_sigma = np.zeros((nb, kmax)), np.empty((nb, 9, 9)), np.zeros((nb, kmax))
    end = 9
    for b in range(nb):
        k = extra[b]
        used = np.concatenate((np.arange(9), np.arange(end, end + k)))  # this model's unknowns among all
        end += k
        Mb, g = M[used][:, used], g_all[used]
        C = inverse(Mb)
        step = -(C @ g)
        c2 = rr + g @ step
        chi2[b] = c2
        dof = 3 * m - 9 - k
        s2 = c2 / dof if dof > 0 else 1.0
        dx[b] = step[:9]
        cov9[b] = C[:9, :9] * s2
        for j in range(k):
            beta[b, j] = step[9 + j]
            beta_sigma[b, j] = math.sqrt(max(C[9 + j, 9 + j] * s2, 0.0))
    return chi2, dx, beta, cov9, beta_sigma
