"""Curved tops: the cap ``h = a + b x + c y + d (x^2 + y^2)`` (a ball, a rounded top) and the
cone ``h = a - k r`` (its apex, which the camera's sampling of the tip usually misses), from the
object's board-frame points (z = height, metres).
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry.compiled import jit, solve_spd
from ..geometry.rect import Rect
from ..geometry.samples import median

REACH = 0.85  # a cone's farthest visible points lie at least this share of its base radius out
CONE_NOISE = 2.0  # a cone's flanks fitted within this many depth noise deviations are a cone


def fit_top(x: np.ndarray, y: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Least-squares ``h = a + b x + c y + d (x^2 + y^2)`` and the standard error of ``d``.

    x, y: (n,) float, board frame, metres, centred near the top. h: (n,) heights, metres.
    Returns ((a, b, c, d), se_d), or None when the system is singular or has too few points.
    """
    if h.size < 8:
        return None
    coef, se_d = _cap(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64), h)
    return (coef, se_d) if np.all(np.isfinite(coef)) and np.isfinite(se_d) else None


@jit
def _cap(x: np.ndarray, y: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, float]:
    """:func:`fit_top` by its normal equations (Cholesky): (coef (4,), se_d), NaN when singular.
    x, y: (n,) float64; h: (n,) float."""
    n = h.size
    M, rhs = np.zeros((4, 4)), np.zeros(4)
    row = np.ones(4)
    for i in range(n):
        row[1], row[2], row[3] = x[i], y[i], x[i] * x[i] + y[i] * y[i]
        for j in range(4):
            rhs[j] += row[j] * np.float64(h[i])
            for m in range(j + 1):
                M[j, m] += row[j] * row[m]
    for j in range(4):
        for m in range(j):
            M[m, j] = M[j, m]
    coef = solve_spd(M, rhs)
    e3 = np.zeros(4)
    e3[3] = 1.0
    inv_33 = solve_spd(M, e3)[3]  # (M^-1)[3, 3]
    rss = 0.0
    for i in range(n):
        r = np.float64(h[i]) - (
            coef[0] + coef[1] * x[i] + coef[2] * y[i] + coef[3] * (x[i] * x[i] + y[i] * y[i])
        )
        rss += r * r
    return coef, math.sqrt(max(rss, 0.0) / (n - 4) * inv_33) if inv_33 >= 0 else math.nan


@jit
def _line_rms(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """Least-squares ``y = a + k x`` of (n,) float64 arrays: (a, k, rms residual)."""
    n = x.size
    xm, ym = x.mean(), y.mean()
    sxy = sxx = 0.0
    for i in range(n):
        dx = x[i] - xm
        sxy += dx * (y[i] - ym)
        sxx += dx * dx
    k = sxy / max(sxx, 1e-12)
    a = ym - k * xm
    ss = 0.0
    for i in range(n):
        e = y[i] - a - k * x[i]
        ss += e * e
    return a, k, math.sqrt(ss / n)


@jit
def _within(b: np.ndarray, cx: float, cy: float, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """(rs, hs) (k,) float64: the xy distance from (cx, cy) and the height of the points of
    b (3, n) float32 (board frame, metres) nearer than ``reach`` to it."""
    n = b.shape[1]
    rs, hs = np.empty(n), np.empty(n)
    k = 0
    for i in range(n):
        r = math.hypot(np.float64(b[0, i]) - cx, np.float64(b[1, i]) - cy)
        if r < reach:
            rs[k], hs[k] = r, b[2, i]
            k += 1
    return rs[:k], hs[:k]


def fit_cone(b: np.ndarray, rect: Rect, noise: float) -> float | None:
    """Apex height of a cone standing in footprint ``rect``, or None when ``b`` is no cone.

    b: (3, n) board-frame points (z = height), metres. The heights within 80 % of the footprint's
    inscribed radius must fall linearly with the distance from its centre (``h = a - k r``,
    ``k`` > 0.5) within three depth noise deviations plus 3 mm, better than a cap; the apex is
    ``a``, which the camera's sampling of the tip (mixed pixels, holes) usually misses.
    """
    radius = 0.5 * float(min(rect.size))
    c = rect.center
    rs, hs = _within(b, float(c[0]), float(c[1]), 0.8 * radius)
    if rs.size < 20 or radius < 0.01:
        return None
    a, k, rms = _line_rms(rs, hs)
    _, _, rms_cap = _line_rms(rs * rs, hs)  # a ball's cap, for comparison
    if k > -0.5 or rms > 3 * noise + 0.003 or rms > 0.8 * rms_cap or a > 2.0 * float(hs.max()):
        return None
    tip = rs < 0.3 * radius  # a cone's tip lies on the line; a bottle's flat cap falls below it
    if np.count_nonzero(tip) >= 5 and float(median(hs[tip] - a - k * rs[tip])) < -(2 * noise + 0.003):
        return None
    return float(a)


def fit_cone_apex(b: np.ndarray, noise: float) -> tuple[np.ndarray, float, float] | None:
    """A cone of unknown axis from its visible flanks: ``(apex_xy (2,), apex height, base radius)``
    of ``h = a - k |xy - apex_xy|`` fitted by Gauss-Newton, or None when ``b`` is no cone.

    For a cone part of whose base is out of view (its stereo shadow, depth holes, the image border)
    the footprint rectangle is not its base, so :func:`fit_cone` cannot centre it. The flanks'
    slope points at the apex from every side the camera sees, which places it. b: (3, n)
    board-frame points (z = height), metres. The cone must fit better than a cap (:func:`fit_top`,
    0.8x its residual) or to the depth noise (:data:`CONE_NOISE` deviations: a cap bent over one
    flank of a cone, all that is seen of it beside the invalid band, fits it nearly as well),
    within three depth noise deviations plus 3 mm, with a slope above 0.5, the apex no higher than
    twice the highest point, every point within 1.2 base radii and some as far as :data:`REACH`
    of it (the flanks reach the board), and the points near the apex on the cone (a bottle's flat
    cap falls below it).
    """
    x, y, h = (b[i].astype(np.float64) for i in range(3))
    m = np.array([x.mean(), y.mean()])
    u, v = x - m[0], y - m[1]  # centred for the cap fit
    cap = fit_top(u, v, h) if h.size >= 30 else None
    if cap is None:
        return None
    c0, c_u, c_v, c_r = cap[0]
    cap_rms = float(np.sqrt(np.mean((c0 + c_u * u + c_v * v + c_r * (u * u + v * v) - h) ** 2)))
    hi = h >= np.quantile(h, 0.95)
    p = np.array([float(h.max()), 1.0, float(x[hi].mean()), float(y[hi].mean())])  # a, k, apex x, y
    p = cone_gauss_newton(x, y, h, p, 15, 1e-5)
    a, k = float(p[0]), float(p[1])
    d = np.hypot(x - p[2], y - p[3])
    rms = float(np.sqrt(np.mean((a - k * d - h) ** 2)))
    if not np.all(np.isfinite(p)) or k < 0.5 or rms > 3 * noise + 0.003:
        return None
    if rms > 0.8 * cap_rms and rms > CONE_NOISE * noise:
        return None
    base = a / k  # the flanks reach the board: a bottle's shoulder stops far short of its "base"
    if a > 2.0 * float(h.max()) or not REACH * base <= float(d.max()) <= 1.2 * base:
        return None
    tip = d < 0.3 * base  # a cone's tip lies on it; a bottle's flat cap falls below it
    if np.count_nonzero(tip) >= 5 and float(median(h[tip] - a + k * d[tip])) < -(2 * noise + 0.003):
        return None
    return p[2:].copy(), a, base


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
