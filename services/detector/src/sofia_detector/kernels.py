"""Compiled building blocks (numba): the Gauss-Newton fit of a cone's apex and small SPD solves.

A cone's apex is fitted by Gauss-Newton over a few thousand points, whose per-step numpy calls
cost more than their arithmetic. They are compiled for
C-contiguous float64 arrays, cached beside the sources (``cache=True``; ``~/.cache/numba`` when
that is read-only) and compiled ahead of the first detection by :func:`warm_kernels`
(``scripts/install.sh``, the detector's image).
"""

from __future__ import annotations

import math

import numba
import numpy as np

jit = numba.njit(cache=True, nogil=True, error_model="numpy")


@jit
def solve_spd(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x of ``A x = b`` for an (n, n) symmetric positive definite A (Cholesky); NaN when it is not."""
    n = A.shape[0]
    L = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1):
            s = A[i, j]
            for m in range(j):
                s -= L[i, m] * L[j, m]
            if i == j:
                if s <= 0.0:
                    return np.full(n, np.nan)
                L[i, i] = math.sqrt(s)
            else:
                L[i, j] = s / L[j, j]
    y = np.empty(n)
    for i in range(n):
        s = b[i]
        for m in range(i):
            s -= L[i, m] * y[m]
        y[i] = s / L[i, i]
    x = np.empty(n)
    for i in range(n - 1, -1, -1):
        s = y[i]
        for m in range(i + 1, n):
            s -= L[m, i] * x[m]
        x[i] = s / L[i, i]
    return x


@jit
def cone_gauss_newton(
    x: np.ndarray, y: np.ndarray, h: np.ndarray, p: np.ndarray, iters: int, tol: float
) -> np.ndarray:
    """Least-squares ``h = a - k |(x, y) - (cx, cy)|`` by Gauss-Newton from ``p`` = (a, k, cx, cy)
    (4,) float64; x, y, h (n,) float64, metres. Stops after ``iters`` steps or once the apex moves
    less than ``tol`` metres; returns the parameters (4,) (NaN when a step cannot be solved)."""
    p = p.copy()
    for _ in range(iters):
        JtJ = np.zeros((4, 4))
        Jtr = np.zeros(4)
        J = np.empty(4)
        for i in range(h.size):
            dx, dy = x[i] - p[2], y[i] - p[3]
            d = max(math.sqrt(dx * dx + dy * dy), 1e-6)
            r = p[0] - p[1] * d - h[i]
            J[0], J[1], J[2], J[3] = 1.0, -d, p[1] * dx / d, p[1] * dy / d
            for a in range(4):
                Jtr[a] += J[a] * r
                for b in range(a + 1):
                    JtJ[a, b] += J[a] * J[b]
        for a in range(4):
            JtJ[a, a] += 1e-9
            for b in range(a):
                JtJ[b, a] = JtJ[a, b]
        step = solve_spd(JtJ, Jtr)
        p -= step
        if not np.isfinite(step).all() or max(abs(step[2]), abs(step[3])) < tol:
            break
    return p


def warm_kernels() -> None:
    """Compile every kernel (or load it from numba's cache), so that the first detection does not
    wait for it."""
    xy = np.random.default_rng(0).normal(size=(40, 2))
    r = np.hypot(xy[:, 0], xy[:, 1])
    cone_gauss_newton(
        xy[:, 0].copy(), xy[:, 1].copy(), 0.05 - 2 * r, np.array([0.05, 1.0, 0.1, 0.1]), 15, 1e-5
    )
