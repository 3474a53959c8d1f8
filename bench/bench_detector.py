"""Detector benchmark: speed and accuracy of ``sofia_detector.detect`` against the baseline.

Baseline (the classic pipeline, measured in the same run on the same clouds): NaN removal, Open3D
``segment_plane`` (5 mm, ransac_n 3, 1000 iterations), the band 1 cm - 30 cm above the plane,
Open3D ``cluster_dbscan`` (eps 1 cm, min_points 10), mean of the largest cluster.

Scenes (``sofia_replay.synth``, 640x480 D435-like clouds in the base frame, board offset up to
3 cm and tilted up to 3 degrees from its configured pose): one object on every red field for each
of box/cylinder/sphere (3-10 cm, random yaw), objects on non-red fields, two objects, empty
boards. Rendered scenes are cached (camera depth + pose + truth) in ``--cache``.

Run: ``.venv/bin/python bench/bench_detector.py`` (about 2-3 minutes; the baseline dominates).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import open3d as o3d
from sofia_detector import detect
from sofia_replay.synth import Camera, make_scene, render_scene
from sofia_schemas import Board

CACHE_VERSION = "detector-v1"
ON_OBJECT_MARGIN = 0.01  # a result "finds" an object when it lies in its bounding box grown by 1 cm


@dataclass
class Case:
    kind: str
    points_base: np.ndarray  # (480, 640, 3) float32, base frame
    objects: list[dict]  # type: ignore[type-arg]


def scene_plan(board: Board, reps: int) -> list[tuple[str, str | None, tuple[int, int] | None]]:
    red = [tuple(a) for a in board.allowed]
    other = [(r, c) for r in range(board.rows) for c in range(board.cols) if (r, c) not in red]
    plan: list[tuple[str, str | None, tuple[int, int] | None]] = []
    for _ in range(reps):
        plan += [("one", shape, fld) for fld in red for shape in ("box", "cylinder", "sphere")]
    plan += [("nonred", shape, fld) for fld in other for shape in ("box", "cylinder", "sphere")]
    plan += [("two", None, None)] * 18 + [("empty", None, None)] * 24
    return plan


def load_cases(board: Board, reps: int, cache: Path) -> list[Case]:
    """Render (or read from the cache) every scene of :func:`scene_plan`."""
    cache = cache / CACHE_VERSION
    cache.mkdir(parents=True, exist_ok=True)
    camera = Camera()
    rays_cam = camera.ray_directions_cam()
    cases = []
    t0 = time.perf_counter()
    for i, (kind, shape, fld) in enumerate(scene_plan(board, reps)):
        path = cache / f"{i:04d}-{kind}-{shape}-{fld}.npz".replace(" ", "")
        if not path.exists():
            rng = np.random.default_rng(10_000 + i)
            frame = render_scene(make_scene(board, kind, rng, shape=shape, fld=fld), rng, camera)  # type: ignore[arg-type]
            truth = json.dumps([o.to_json() for o in frame.scene.objects])
            np.savez(path, z_cam=frame.render.points_cam[..., 2], T_base_cam=frame.T_base_cam, truth=truth)
        data = np.load(path)
        points_cam = (rays_cam * data["z_cam"].astype(np.float64)[..., None]).astype(np.float32)
        T = data["T_base_cam"]
        points_base = (points_cam.astype(np.float64) @ T[:3, :3].T + T[:3, 3]).astype(np.float32)
        cases.append(Case(kind, points_base, json.loads(str(data["truth"]))))
    print(f"{len(cases)} scenes ready in {time.perf_counter() - t0:.0f} s (cache {cache})")
    return cases


def baseline(points_base: np.ndarray) -> np.ndarray | None:
    """Centre of the largest cluster above the RANSAC plane (3,), or None."""
    p = points_base.reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)].astype(np.float64)
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(p))
    (a, b, c, d), _ = pcd.segment_plane(distance_threshold=0.005, ransac_n=3, num_iterations=1000)
    sign = 1.0 if c > 0 else -1.0
    h = sign * (p @ np.array([a, b, c]) + d)
    idx = np.flatnonzero((h > 0.01) & (h < 0.30))
    if idx.size == 0:
        return None
    band = pcd.select_by_index(idx)
    labels = np.asarray(band.cluster_dbscan(eps=0.01, min_points=10))
    if labels.size == 0 or labels.max() < 0:
        return None
    largest = int(np.argmax(np.bincount(labels[labels >= 0])))
    return np.asarray(band.points)[labels == largest].mean(axis=0)


def on_object(p_base: np.ndarray, obj: dict) -> bool:  # type: ignore[type-arg]
    """True when ``p_base`` (3,) lies inside the object's bounding box grown by ON_OBJECT_MARGIN."""
    T = np.array(obj["T_base_obj"])
    p_obj = T[:3, :3].T @ (np.asarray(p_base) - T[:3, 3])
    return bool(np.all(np.abs(p_obj) <= np.array(obj["extents"]) / 2 + ON_OBJECT_MARGIN))


def pct(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if values else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=12, help="scenes per red field and shape (default 12)")
    ap.add_argument("--repeat", type=int, default=5, help="timed detect calls per cloud (default 5)")
    ap.add_argument("--cache", type=Path, default=Path("/tmp/sofia-bench-cache"))
    args = ap.parse_args()
    board = Board.default()
    cases = load_cases(board, args.reps, args.cache)

    for c in cases[:5]:  # warm-up
        detect(c.points_base, board)
    ours_ms: list[float] = []
    base_ms: list[float] = []
    ours_err: dict[str, list[float]] = {}
    base_err: dict[str, list[float]] = {}
    centroid_err: list[float] = []
    unorg_err: list[float] = []
    unorg_ms: list[float] = []
    n_true = found = field_ok = nonred = nonred_flagged = false_objects = false_on_empty = 0
    base_found = base_false_empty = base_one = 0
    for c in cases:
        for _ in range(args.repeat):
            t = time.perf_counter()
            det = detect(c.points_base, board)
            ours_ms.append((time.perf_counter() - t) * 1e3)
        centers = np.array([o.center for o in det.objects]).reshape(-1, 3)
        used = set()
        for o in c.objects:
            n_true += 1
            d = (
                np.linalg.norm(centers - np.array(o["center"]), axis=1)
                if len(centers)
                else np.array([np.inf])
            )
            j = int(np.argmin(d))
            if np.isfinite(d[j]) and on_object(centers[j], o):
                found += 1
                used.add(j)
                obj = det.objects[j]
                ours_err.setdefault(o["shape"], []).append(float(d[j]) * 1e3)
                centroid_err.append(float(np.linalg.norm(np.array(obj.centroid) - o["center"])) * 1e3)
                field_ok += tuple(obj.field or ()) == tuple(o["field"]) and obj.allowed == o["allowed"]
                if not o["allowed"]:
                    nonred += 1
                    nonred_flagged += not obj.allowed
        false_objects += len(det.objects) - len(used)
        false_on_empty += len(det.objects) if c.kind == "empty" else 0

        shuffled = c.points_base.reshape(-1, 3)
        t = time.perf_counter()
        udet = detect(shuffled, board)
        unorg_ms.append((time.perf_counter() - t) * 1e3)
        ucenters = np.array([o.center for o in udet.objects]).reshape(-1, 3)
        for o in c.objects:
            if len(ucenters):
                unorg_err.append(
                    float(np.min(np.linalg.norm(ucenters - np.array(o["center"]), axis=1))) * 1e3
                )

        t = time.perf_counter()
        b = baseline(c.points_base)
        base_ms.append((time.perf_counter() - t) * 1e3)
        if c.kind == "empty":
            base_false_empty += b is not None
        elif len(c.objects) == 1:
            base_one += 1
            o = c.objects[0]
            hit = b is not None and on_object(b, o)
            base_found += hit
            err = float(np.linalg.norm(b - np.array(o["center"]))) * 1e3 if hit else float("inf")
            base_err.setdefault(o["shape"], []).append(err)

    n_empty = sum(c.kind == "empty" for c in cases)
    ours_all = [e for v in ours_err.values() for e in v]
    base_all = [e for v in base_err.values() for e in v]
    base_found_err = [e for e in base_all if np.isfinite(e)]
    med_ours, med_base = float(np.median(ours_ms)), float(np.median(base_ms))
    print()
    print(
        f"Detector benchmark: {len(cases)} synthetic 640x480 clouds ({n_true} objects, {n_empty} empty boards)"
    )
    print()
    print("| | SofIA `detect` | baseline (RANSAC + DBSCAN, mean) | ratio |")
    print("|---|---|---|---|")
    print(
        f"| median time per cloud | {med_ours:.2f} ms | {med_base:.1f} ms | {med_base / med_ours:.0f}x faster |"
    )
    print(f"| p90 time per cloud | {pct(ours_ms, 90):.2f} ms | {pct(base_ms, 90):.1f} ms | |")
    print(
        f"| centre error p50 / p95 / max (3D) | {pct(ours_all, 50):.2f} / {pct(ours_all, 95):.2f} / "
        f"{max(ours_all):.2f} mm | {pct(base_found_err, 50):.1f} / {pct(base_found_err, 95):.1f} / "
        f"{max(base_found_err):.1f} mm (objects it found) | |"
    )
    print(
        f"| objects found (result on the object) | {found}/{n_true} ({100 * found / n_true:.1f} %) | "
        f"{base_found}/{base_one} single-object scenes ({100 * base_found / base_one:.1f} %) | |"
    )
    print(f"| false objects on empty boards | {false_on_empty} ({n_empty} boards) | {base_false_empty} | |")
    print(f"| false objects, all scenes | {false_objects} | | |")
    print(f"| field and allowed flag correct | {field_ok}/{found} | no fields | |")
    print(f"| objects on non-red fields flagged `allowed: false` | {nonred_flagged}/{nonred} | no fields | |")
    print(
        f"| centroid (mean of visible points) vs true centre, p50 / p95 | {pct(centroid_err, 50):.1f} / {pct(centroid_err, 95):.1f} mm | | |"
    )
    print(
        f"| unorganized (flattened) clouds: median time, p95 / max error | {np.median(unorg_ms):.1f} ms, {pct(unorg_err, 95):.2f} / {max(unorg_err):.2f} mm | | |"
    )
    print()
    print("Centre error by shape (mm, 3D):")
    print()
    print(
        "| shape | n | SofIA p50 | SofIA p95 | SofIA max | baseline p50 | baseline p95 | baseline max | baseline on another thing |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for shape in ("box", "cylinder", "sphere"):
        o, b = ours_err.get(shape, []), base_err.get(shape, [])
        bf = [e for e in b if np.isfinite(e)]
        print(
            f"| {shape} | {len(o)} | {pct(o, 50):.2f} | {pct(o, 95):.2f} | {max(o):.2f} | "
            f"{pct(bf, 50):.1f} | {pct(bf, 95):.1f} | {max(bf) if bf else float('nan'):.1f} | {len(b) - len(bf)}/{len(b)} |"
        )
    print()
    ok_speed = med_ours <= 5.0 and med_base / med_ours >= 10
    ok_acc = pct(ours_all, 95) <= 5.0 and max(ours_all) <= 8.0 and found == n_true and false_on_empty == 0
    ok_flags = nonred_flagged == nonred
    print(
        f"targets: speed {'met' if ok_speed else 'MISSED'} (<= 5 ms, >= 10x); accuracy {'met' if ok_acc else 'MISSED'} "
        f"(p95 <= 5 mm, max <= 8 mm, all found, 0 false on empty); non-red flags {'met' if ok_flags else 'MISSED'}"
    )


if __name__ == "__main__":
    main()
