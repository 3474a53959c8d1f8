"""Find the dark calibration blob on the white sheet in an organized RGB-D cloud.

The blob's 3D centre is the area centroid of its pixels cast along their rays onto the plane fitted
to the sheet around it (robust to missing depth on the blob), each weighted by the area it covers
there, 1 / |n . r|^3 for a ray r = (x/z, y/z, 1) and the plane's unit normal n: the disc's centre in
any view (a tilted disc's pixel centroid is pulled to its near side). Specular glare (saturated
pixels, bright depth holes) on the rim: the centre comes from an ellipse fitted to the rest of the
rim, and the confidence drops by the fraction of the rim the glare touches.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from .errors import BlobAmbiguous, BlobCutByEdge, BlobNoDepth, BlobNotFound, InputMismatch

DARK = 90  # grey level below which a pixel may belong to the blob
BRIGHT = 170  # grey level above which a pixel belongs to the sheet
MIN_PIXELS = 30
RING_PX = 6
MIN_WHITE_RING = 0.75  # fraction of the blob's surrounding ring that must be sheet
AMBIGUOUS_RATIO = 0.3  # a second blob this large relative to the first is ambiguous
SATURATED = 250  # grey level of specular glare (the sheet itself stays below)
MIN_CLEAN_RIM = 12  # rim pixels free of glare needed to fit the blob's outline


@dataclass
class Blob:
    p_cam: np.ndarray  # (3,) blob centre, camera optical frame, metres
    confidence: float  # 0..1
    n_pixels: int
    centroid_px: tuple[float, float]  # (u, v)


def _rays(points_cam: np.ndarray) -> tuple[float, float, float, float]:
    """Intrinsics (fx, cx, fy, cy) fitted to the cloud: x/z = (u - cx)/fx, y/z = (v - cy)/fy."""
    H, W, _ = points_cam.shape
    v, u = np.mgrid[0:H:4, 0:W:4]
    p = points_cam[::4, ::4]
    ok = np.isfinite(p).all(axis=2) & (p[..., 2] > 0)
    if ok.sum() < 20:
        raise BlobNoDepth(int(ok.size), int(ok.sum()))
    A = np.c_[u[ok], np.ones(ok.sum())]
    kx, bx = np.linalg.lstsq(A, p[ok][:, 0] / p[ok][:, 2], rcond=None)[0]
    A = np.c_[v[ok], np.ones(ok.sum())]
    ky, by = np.linalg.lstsq(A, p[ok][:, 1] / p[ok][:, 2], rcond=None)[0]
    return 1.0 / kx, -bx / kx, 1.0 / ky, -by / ky


def _plane(points: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Plane n.p = d through (m, 3) points, trimmed once; returns (n, d, rms residual)."""
    for _ in range(2):
        c = points.mean(axis=0)
        n = np.linalg.svd(points - c, full_matrices=False)[2][2]
        r = (points - c) @ n
        keep = np.abs(r) <= max(3.0 * 1.4826 * np.median(np.abs(r)), 1e-4)
        points = points[keep]
    return n, float(n @ c), float(np.sqrt(np.mean(r[keep] ** 2)))


def _glare(mask: np.ndarray, grey: np.ndarray, points_cam: np.ndarray) -> tuple[np.ndarray, float]:
    """Rim pixels of the blob free of glare (k, 2) as (u, v), and the fraction of the rim that
    touches specular pixels (saturated, or without depth while bright)."""
    vv, uu = np.nonzero(mask)
    r0, c0 = max(int(vv.min()) - 4, 0), max(int(uu.min()) - 4, 0)
    win = (slice(r0, int(vv.max()) + 5), slice(c0, int(uu.max()) + 5))  # the blob and its rim only
    m, g = mask[win], grey[win]
    rim = m & ~ndimage.binary_erosion(m)
    holes = ~np.isfinite(points_cam[win]).all(axis=2) & (g > BRIGHT)
    touched = rim & ndimage.binary_dilation((g >= SATURATED) | holes, iterations=2)
    rv, ru = np.nonzero(rim & ~touched)
    return np.c_[ru + c0, rv + r0].astype(np.float64), float(touched.sum()) / max(int(rim.sum()), 1)


def _plane_centroid(
    uu: np.ndarray,
    vv: np.ndarray,
    intrinsics: tuple[float, float, float, float],
    normal: np.ndarray,
    d: float,
) -> np.ndarray:
    """Area centroid (3,) camera frame, metres, of pixels (u, v) (m,) cast onto the plane n.p = d
    (unit normal ``normal`` (3,), camera frame): each ray r = ((u - cx)/fx, (v - cy)/fy, 1) meets it
    at r d / (n . r), covering an area proportional to 1 / |n . r|^3 (see the module docstring)."""
    fx, cx, fy, cy = intrinsics
    rays = np.stack([(uu - cx) / fx, (vv - cy) / fy, np.ones(len(uu))], axis=1)
    nr = rays @ normal
    area = 1.0 / np.abs(nr) ** 3
    return np.asarray((area * d / nr) @ rays / area.sum())


def find_blob(points_cam: np.ndarray, rgb: np.ndarray) -> Blob:
    """The blob in an organized cloud.

    points_cam: (H, W, 3) float, camera optical frame, metres, NaN where missing.
    rgb: (H, W, 3) uint8. Raises BlobNotFound, BlobCutByEdge, BlobAmbiguous or BlobNoDepth.
    """
    points_cam, rgb = np.asarray(points_cam, dtype=np.float64), np.asarray(rgb)
    if points_cam.ndim != 3 or points_cam.shape[2] != 3:
        raise InputMismatch(f"points_cam must be an organized cloud (H, W, 3), got {points_cam.shape}")
    if rgb.shape != points_cam.shape:
        raise InputMismatch(f"rgb must have the cloud's shape {points_cam.shape}, got {rgb.shape}")
    H, W, _ = rgb.shape
    grey = rgb.astype(np.float32).mean(axis=2)
    bright = grey > BRIGHT
    labels, n = ndimage.label(grey < DARK)
    if n == 0:
        raise BlobNotFound(f"no pixel darker than {DARK} (darkest grey {grey.min():.0f})")
    sizes = ndimage.sum_labels(np.ones_like(grey), labels, index=np.arange(1, n + 1))
    slices = ndimage.find_objects(labels)
    found: list[tuple[int, int]] = []
    cut: list[tuple[int, int, int, int]] = []
    for k in np.flatnonzero(sizes >= MIN_PIXELS):
        sl = slices[k]
        r0, r1 = max(sl[0].start - RING_PX, 0), min(sl[0].stop + RING_PX, H)
        c0, c1 = max(sl[1].start - RING_PX, 0), min(sl[1].stop + RING_PX, W)
        mask = labels[r0:r1, c0:c1] == k + 1
        ring = ndimage.binary_dilation(mask, iterations=RING_PX) & ~mask
        around = bright[r0:r1, c0:c1][ring]
        if around.size == 0 or around.mean() < MIN_WHITE_RING:
            continue  # not enclosed by the sheet (or nothing around it in view): table edge, gripper, shadow
        touches = sl[0].start == 0 or sl[1].start == 0 or sl[0].stop == H or sl[1].stop == W
        if touches:
            cut.append((sl[0].start, sl[0].stop - 1, sl[1].start, sl[1].stop - 1))
        else:
            found.append((int(sizes[k]), int(k) + 1))
    if not found:
        if cut:
            raise BlobCutByEdge(cut[0], (H, W))
        raise BlobNotFound(f"none of {n} dark regions is a blob of >= {MIN_PIXELS} pixels on the white sheet")
    found.sort(reverse=True)
    if len(found) > 1 and found[1][0] >= AMBIGUOUS_RATIO * found[0][0]:
        raise BlobAmbiguous([s for s, _ in found])
    size, label = found[0]
    mask = labels == label
    vv, uu = np.nonzero(mask)
    u_c, v_c = float(uu.mean()), float(vv.mean())
    clean_rim, glare = _glare(mask, grey, points_cam)
    outline_centre = False
    if glare > 0.0 and len(clean_rim) >= MIN_CLEAN_RIM:  # glare eats part of the blob: its centre
        import cv2

        centre = cv2.fitEllipse(clean_rim.astype(np.float32))[0]  # from the outline that is left
        if np.hypot(centre[0] - u_c, centre[1] - v_c) < 0.5 * np.sqrt(size):
            (u_c, v_c), outline_centre = centre, True
    ring = ndimage.binary_dilation(mask, iterations=RING_PX) & ~mask & bright
    on_plane = (mask | ring) & np.isfinite(points_cam).all(axis=2)
    n_valid = int((mask & on_plane).sum())
    if on_plane.sum() < 20:
        raise BlobNoDepth(size, n_valid)
    fx, cx, fy, cy = _rays(points_cam)
    normal, d, rms = _plane(points_cam[on_plane])
    ray = np.array([(u_c - cx) / fx, (v_c - cy) / fy, 1.0])
    if abs(float(normal @ ray)) < 1e-3:
        raise BlobNotFound(f"the sheet is seen edge-on (normal {np.round(normal, 3).tolist()})")
    if outline_centre:
        p_cam = ray * (d / float(normal @ ray))
    else:
        p_cam = _plane_centroid(uu, vv, (fx, cx, fy, cy), normal, d)
    contrast = float(grey[ring].mean() - grey[mask].mean()) if ring.any() else 0.0
    fill = size / max(np.pi * 0.25 * np.ptp(uu + 1) * np.ptp(vv + 1), 1.0)  # 1 for a full ellipse
    confidence = float(
        np.clip(contrast / 150.0, 0, 1) * np.clip(fill, 0, 1) * np.exp(-rms / 0.005) * (1.0 - glare)
    )
    return Blob(p_cam, confidence, size, (u_c, v_c))
