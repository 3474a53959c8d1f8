"""One sphere of unknown radius seen in several views: the radius shared by all of them.

A radius fitted per view trades off against the centre along the view ray (only the near cap is
seen). Each view is segmented on its own (:func:`~.sphere.segment_sphere`), then either ``joint``
(default): one soft-L1 least-squares fit of every centre and the one radius along the viewing rays
(:func:`~.sphere.ray_residuals`, sparse Jacobian), each view's residuals over its own RMS; or
``median``: the median per-view radius, each centre refitted with it (the joint fit's start).
Synthetic 25 mm ball at 0.45-0.9 m, D435 depth noise, 12 sets of 10 views: centre error 0.10 mm
RMS (joint), 0.11 mm (median), 0.22 mm (a radius per view; 0.10 mm with the radius given);
RegHEC's real sphere set: all agree (1.05 mm fit RMS). ``bench/bench_calibrator_targets.py``.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix

from ..errors import InputMismatch
from .sphere import (
    DEFAULT_INLIER_M,
    Sphere,
    SphereNotFound,
    find_sphere,
    ray_residuals,
    refine_sphere,
    segment_sphere,
)

METHODS = ("joint", "median")
MAX_POINTS_PER_VIEW = 3000  # the joint fit takes a random subset of each view's inliers beyond this


def shared_spheres(
    clouds_cam: list[np.ndarray], inlier_m: float = DEFAULT_INLIER_M, method: str = "joint"
) -> list[Sphere]:
    """The sphere of each view, all of one fitted radius. clouds_cam: n clouds (m_i, 3) or
    (h, w, 3), camera optical frame, metres (each view in its own camera pose). Returns n
    :class:`Sphere` (centre, shared radius, the centre's 1-sigma), camera optical frame, metres.
    Raises :class:`~.sphere.SphereNotFound` naming the view where no sphere is found."""
    if len(clouds_cam) == 0:
        raise InputMismatch("no clouds: need one point cloud per view")
    segments = []
    for i, cloud in enumerate(clouds_cam):
        try:
            segments.append(segment_sphere(cloud, None, inlier_m))
        except SphereNotFound as e:
            reason = str(e).removeprefix("no sphere found: ")
            raise SphereNotFound(f"view {i + 1} of {len(clouds_cam)}: {reason}") from e
    return fit_shared(segments, method)


def fit_shared(segments: list[tuple[np.ndarray, np.ndarray, float]], method: str = "joint") -> list[Sphere]:
    """The spheres of segmented views, one radius shared: segments are n (inliers (k_i, 3), rough
    centre (3,), rough radius) of :func:`~.sphere.segment_sphere`, camera optical frame, metres."""
    if method not in METHODS:
        raise InputMismatch(f"method must be one of {list(METHODS)}, got {method!r}")
    singles = [refine_sphere(pts, c, r, True) for pts, c, r in segments]
    radius = float(np.median([s.radius_m for s in singles]))  # robust to a view whose fit ran off
    fixed = [refine_sphere(pts, one.p_cam if abs(one.radius_m - radius) < 0.2 * radius else c, radius, False)
             for (pts, c, _), one in zip(segments, singles, strict=True)]  # fmt: skip
    return fixed if method == "median" or len(segments) == 1 else _joint(segments, fixed)


def _joint(segments: list[tuple[np.ndarray, np.ndarray, float]], starts: list[Sphere]) -> list[Sphere]:
    """Every centre and one radius by one least-squares fit (see the module's text), from the
    median radius's fits ``starts``."""
    rng = np.random.default_rng(0)
    views = []
    for pts, _, _ in segments:
        views.append(
            pts[rng.choice(len(pts), MAX_POINTS_PER_VIEW, replace=False)]
            if len(pts) > MAX_POINTS_PER_VIEW
            else pts
        )
    n = len(views)
    counts = np.array([len(v) for v in views])
    view_of = np.repeat(np.arange(n), counts)  # (m,) the view of each point
    points = np.concatenate(views)  # (m, 3), each in its own view's camera frame
    ranges = np.linalg.norm(points, axis=1)
    medians = np.array([np.median(np.linalg.norm(v, axis=1)) for v in views])[view_of]
    # (m,) whitening: each view's RMS along the rays, the depth noise growing with the square of the range
    rms = [
        np.sqrt(np.mean(ray_residuals(v, s.p_cam, s.radius_m)[0] ** 2))
        for v, s in zip(views, starts, strict=True)
    ]
    w = (medians / ranges) ** 2 / np.maximum(rms, 1e-5)[view_of]
    rows = np.repeat(np.arange(len(points)), 4)
    cols = np.c_[3 * view_of[:, None] + np.arange(3), np.full(len(points), 3 * n)].ravel()

    def rays(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # residuals (m,), Jacobian rows (m, 4)
        return ray_residuals(points, x[: 3 * n].reshape(n, 3)[view_of], x[3 * n])

    def resid(x: np.ndarray) -> np.ndarray:
        return np.asarray(w * rays(x)[0])

    def jac(x: np.ndarray) -> csr_matrix:
        vals = rays(x)[1] * w[:, None]
        return csr_matrix((vals.ravel(), (rows, cols)), shape=(len(points), 3 * n + 1))

    x0 = np.r_[np.concatenate([s.p_cam for s in starts]), starts[0].radius_m]
    sol = least_squares(resid, x0, jac=jac, loss="soft_l1", f_scale=1.0, x_scale=0.01, tr_solver="lsmr")
    r = sol.fun
    s2 = float(r @ r) / max(len(r) - len(x0), 1)
    J = sol.jac
    cov = np.linalg.pinv((J.T @ J).toarray()) * s2
    radius = float(sol.x[3 * n])
    out = []
    for i in range(n):
        b = slice(3 * i, 3 * i + 3)
        c = sol.x[b]
        res = np.linalg.norm(views[i] - c, axis=1) - radius
        out.append(Sphere(
            p_cam=c, radius_m=radius, sigma_cam=np.sqrt(np.maximum(cov.diagonal()[b], 0.0)),
            covariance=cov[b, b], n_inliers=len(segments[i][0]), rms_m=float(np.sqrt(np.mean(res**2))),
        ))  # fmt: skip
    return out


def sphere_centres(
    clouds_cam: list[np.ndarray], radius_m: float | None = None, inlier_m: float = DEFAULT_INLIER_M
) -> tuple[np.ndarray, np.ndarray]:
    """The calibration points of n views of a sphere: (p_cam (n, 3), sigma_cam (n, 3)), camera
    optical frame, metres; each view's cloud (m_i, 3) or (h, w, 3), metres. radius_m: the known
    radius, or None for one radius fitted to all the views (:func:`shared_spheres`).
    ``p_cam`` goes where the blob positions go (:func:`sofia_calibrator.calibrate`, with
    ``sigma=sigma_cam`` to weight the views by their fit's uncertainty)."""
    if radius_m is None:
        spheres = shared_spheres(clouds_cam, inlier_m)
    else:
        spheres = [find_sphere(c, radius_m, inlier_m) for c in clouds_cam]
    return np.array([s.p_cam for s in spheres]), np.array([s.sigma_cam for s in spheres])
