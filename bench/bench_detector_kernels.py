"""The detector's numba kernels against the numpy forms they replace, on the realistic scenes' inputs.

Each kernel's calls during detections of the cached ``bench_detector_real.py`` scenes are recorded
(the arguments as the detector passes them), then each call is timed through the kernel and
through its numpy form (best of ``--repeat``), whose results must agree. Printed per kernel: calls
per cloud, median time per call of each form, the ratio, and the time per cloud each form costs.
The numbers stand in the kernels' docstrings.

Run: ``.venv/bin/python bench/bench_detector_kernels.py`` (the scenes cached by
``bench_detector_real.py``; about a minute).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from bench_detector_real import CACHE_VERSION, load_case
from sofia_detector import detect
from sofia_detector.depth import clean
from sofia_detector.geometry import points
from sofia_detector.geometry.grid import where
from sofia_schemas import Board


def np_points_in_frame(p_a: np.ndarray, R_t: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """``points._points_in_frame`` in numpy: elementwise, float32 (BLAS would thread)."""
    x, y, z = np.moveaxis(p_a, -1, 0).astype(np.float32)
    return np.stack([R_t[i, 0] * x + R_t[i, 1] * y + R_t[i, 2] * z - offset[i] for i in range(3)])


NEIGHBOURS = np.array([(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1) if i or j])


def np_consistent_at(c: np.ndarray, mask: np.ndarray, d2: float, min_neighbours: int) -> np.ndarray:
    """``clean._consistent_at`` in numpy: the 8 neighbours of the mask's pixels gathered at once."""
    _, h, w = c.shape
    pad = np.pad(c, ((0, 0), (1, 1), (1, 1)), constant_values=np.nan).reshape(3, -1)
    r, q = where(mask)
    at = (r + 1) * (w + 2) + q + 1
    d = pad[:, at[None] + (NEIGHBOURS[:, :1] * (w + 2) + NEIGHBOURS[:, 1:])] - pad[:, None, at]
    with np.errstate(invalid="ignore"):
        near = np.count_nonzero(np.einsum("kij,kij->ij", d, d) < d2, axis=0)
    out = np.zeros((h, w), dtype=bool)
    out[r, q] = near >= min_neighbours
    return out


def same(a: Any, b: Any) -> bool:
    """Whether two kernel results agree (arrays exactly or within 1e-6 relative, tuples item by item)."""
    if isinstance(a, tuple):
        return all(same(x, y) for x, y in zip(a, b, strict=True))
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype.kind == "f" or b.dtype.kind == "f":
        return bool(np.allclose(a, b, rtol=1e-6, atol=1e-7, equal_nan=True))
    return bool(np.array_equal(a, b))


KERNELS: dict[str, tuple[Any, str, Callable[..., Any]]] = {
    "points._points_in_frame": (points, "_points_in_frame", np_points_in_frame),
    "clean._consistent_at": (clean, "_consistent_at", np_consistent_at),
}


KERNEL_OF: dict[str, Any] = {name: getattr(mod, attr) for name, (mod, attr, _) in KERNELS.items()}


def best_us(f: Callable[..., Any], args: tuple[Any, ...], repeat: int) -> float:
    """Fastest of ``repeat`` calls of ``f(*args)``."""
    out = []
    for _ in range(repeat):
        a = tuple(x.copy() if isinstance(x, np.ndarray) and x.flags.writeable else x for x in args)
        t = time.perf_counter()
        f(*a)
        out.append(time.perf_counter() - t)
    return min(out) * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=40, help="cached scenes used (spread over the categories)")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--cache", type=Path, default=Path("/tmp/sofia-bench-cache"))
    args = ap.parse_args()
    paths = sorted((args.cache / CACHE_VERSION).glob("*.npz"))
    paths = paths[:: max(1, len(paths) // args.scenes)][: args.scenes]
    if not paths:
        raise SystemExit(
            f"no cached scenes in {args.cache / CACHE_VERSION}: run bench_detector_real.py first"
        )
    board = Board.default()
    calls: dict[str, list[tuple[Any, ...]]] = {name: [] for name in KERNELS}
    for name, (mod, attr, _) in KERNELS.items():

        def record(*a: Any, _k: Any = KERNEL_OF[name], _n: str = name) -> Any:
            calls[_n].append(tuple(x.copy() if isinstance(x, np.ndarray) else x for x in a))
            return _k(*a)

        setattr(mod, attr, record)
    for path in paths:
        c = load_case(path, board)
        detect(c.points_base, c.board, rgb=c.rgb)
    for name, (mod, attr, _) in KERNELS.items():
        setattr(mod, attr, KERNEL_OF[name])
    print(f"\nDetector kernels against their numpy forms: {len(paths)} realistic scenes\n")
    print(
        "| kernel | calls per cloud | kernel us per call (median) | numpy us per call (median) "
        "| numpy / kernel | kernel ms per cloud | numpy ms per cloud | results agree |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name, (_, _, numpy_form) in KERNELS.items():
        kernel = KERNEL_OF[name]
        t_k = [best_us(kernel, a, args.repeat) for a in calls[name]]
        t_n = [best_us(numpy_form, a, args.repeat) for a in calls[name]]
        agree = all(same(kernel(*_copies(a)), numpy_form(*_copies(a))) for a in calls[name])
        per = len(calls[name]) / len(paths)
        print(
            f"| {name} | {per:.1f} | {np.median(t_k):.1f} | {np.median(t_n):.1f} "
            f"| {np.median(t_n) / np.median(t_k):.1f} | {sum(t_k) / len(paths) / 1e3:.3f} "
            f"| {sum(t_n) / len(paths) / 1e3:.3f} | {agree} |"
        )


def _copies(a: tuple[Any, ...]) -> tuple[Any, ...]:
    return tuple(x.copy() if isinstance(x, np.ndarray) else x for x in a)


if __name__ == "__main__":
    main()
