"""Compiled building blocks (numba): the convex hull and the rectangle of least area of 2-D points,
and the Gauss-Newton fit of a cone's apex.

Every object's footprint and the board's outline are rectangles of least area around a few hundred
outline points. Qhull (through SciPy) answered these in 80 us on average but now and then in
several milliseconds; Andrew's monotone chain and the rotating-calipers search over the hull's
edges run here in a few microseconds. A cone's apex is fitted by Gauss-Newton over a few thousand
points, whose per-step numpy calls cost more than their arithmetic. They are compiled for
C-contiguous float64 arrays, cached beside the sources (``cache=True``; ``~/.cache/numba`` when
that is read-only) and compiled ahead of the first detection by :func:`warm_kernels`
(``scripts/install.sh``, the detector's image).
"""

from __future__ import annotations

import math

import numba
import numpy as np

jit = numba.njit(cache=True, nogil=True, error_model="numpy")
QUARTER = math.pi / 2


@jit
def _turn(xy: np.ndarray, a: int, b: int, c: int) -> float:
    """Cross product (b - a) x (c - a) of points a, b, c of ``xy``: > 0 for a left turn."""
    return (xy[b, 0] - xy[a, 0]) * (xy[c, 1] - xy[a, 1]) - (xy[b, 1] - xy[a, 1]) * (xy[c, 0] - xy[a, 0])


@jit
def hull_indices(xy: np.ndarray) -> np.ndarray:
    """(k,) indices into ``xy`` (n, 2) float64 of its convex hull's vertices, counter-clockwise
    (Andrew's monotone chain). Collinear and repeated points are not vertices: k < 3 when the
    points span no area."""
    n = xy.shape[0]
    if n < 2:
        return np.arange(n)
    by_y = np.argsort(xy[:, 1], kind="mergesort")
    order = by_y[np.argsort(xy[by_y, 0], kind="mergesort")]  # by x, then y
    chain = np.empty(2 * n, dtype=np.intp)
    k = 0
    for i in range(n):  # lower chain, left to right
        p = order[i]
        while k >= 2 and _turn(xy, chain[k - 2], chain[k - 1], p) <= 0.0:
            k -= 1
        chain[k] = p
        k += 1
    lower = k + 1
    for i in range(n - 2, -1, -1):  # upper chain, right to left
        p = order[i]
        while k >= lower and _turn(xy, chain[k - 2], chain[k - 1], p) <= 0.0:
            k -= 1
        chain[k] = p
        k += 1
    return chain[: k - 1].copy()  # the last point is the first


@jit
def least_area_box(v: np.ndarray, max_yaw: float) -> tuple[float, np.ndarray, np.ndarray]:
    """The rectangle of least area around polygon ``v`` (k, 2) float64 (a convex hull, vertices in
    order) with one side along one of its edges: ``(yaw, lo (2,), hi (2,))``, the yaw of its first
    axis folded into ``[-pi/4, pi/4)`` and the bounds of the vertices along its two axes. Only edges
    whose folded yaw is within ``max_yaw`` (radians) count; yaw 0 when none does."""
    k = v.shape[0]
    best = np.inf
    yaw_best = 0.0
    lo_best = np.zeros(2)
    hi_best = np.zeros(2)
    for e in range(k + 1):  # every edge, then yaw 0 (used only when no edge is within max_yaw)
        if e < k:
            f = (e + 1) % k
            yaw = (math.atan2(v[f, 1] - v[e, 1], v[f, 0] - v[e, 0]) + math.pi / 4) % QUARTER - math.pi / 4
            if abs(yaw) > max_yaw:
                continue
        elif best < np.inf:
            break
        else:
            yaw = 0.0
        c, s = math.cos(yaw), math.sin(yaw)
        u_lo = v_lo = np.inf
        u_hi = v_hi = -np.inf
        for i in range(k):
            u = c * v[i, 0] + s * v[i, 1]
            w = -s * v[i, 0] + c * v[i, 1]
            u_lo, u_hi = min(u_lo, u), max(u_hi, u)
            v_lo, v_hi = min(v_lo, w), max(v_hi, w)
        area = (u_hi - u_lo) * (v_hi - v_lo)
        if area < best:
            best, yaw_best = area, yaw
            lo_best[0], lo_best[1], hi_best[0], hi_best[1] = u_lo, v_lo, u_hi, v_hi
    return yaw_best, lo_best, hi_best


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
    v = xy[hull_indices(xy)]
    least_area_box(v, np.inf)
    least_area_box(v, 0.1)
    r = np.hypot(xy[:, 0], xy[:, 1])
    cone_gauss_newton(
        xy[:, 0].copy(), xy[:, 1].copy(), 0.05 - 2 * r, np.array([0.05, 1.0, 0.1, 0.1]), 15, 1e-5
    )
