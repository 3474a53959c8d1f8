"""The detector against a previous release of it, on the realistic scenes, in one run.

Both releases detect every cached scene of ``bench_detector_real.py`` (organized, and flattened to
N x 3 through the unorganized path), their calls alternating so that the machine's load falls on
both alike. Printed: per category the objects found / missed, false objects, centre error p50 /
p95 / max and colours right of each release; confidence calibration; how far apart the two
releases' objects are (centre, confidence); and the median time per call at each resolution, with
the ratio and the speed targets.

The previous release is a copy of the ``sofia_detector`` package renamed, for instance::

    mkdir -p /tmp/prev && git archive main services/detector/src/sofia_detector | tar -x -C /tmp/prev
    mv /tmp/prev/services/detector/src/sofia_detector /tmp/prev/sofia_detector_prev

Run: ``.venv/bin/python bench/bench_detector_release.py --previous /tmp/prev`` (renders the scenes
that ``bench_detector_real.py`` has not cached yet).
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from bench_detector import pct
from bench_detector_real import TARGET_MS, Case, load_case, render_cases, score
from sofia_detector import detect
from sofia_replay.synth.realism import CATEGORIES
from sofia_schemas import Board

TOL_P = 0.2  # mm: p50 and p95 of a category may grow this much (a fall beyond it is listed as better)
TOL_MAX = 0.5  # mm: its largest error this much
TOL_CENTRE, TOL_CONF = 0.01, 1e-3  # mm, confidence: one object of both releases
TOL_RATIO = 1.3  # time per call at most this many times the previous release's


class Tally:
    """One release's results: per category (and ``flattened``) counts and errors, its times."""

    def __init__(self) -> None:
        self.rows: dict[str, dict[str, list[Any]]] = {}
        self.ms: dict[tuple[int, int], list[float]] = {}
        self.conf: list[tuple[float, float]] = []

    def add(self, category: str, case: Case, det: Any) -> None:
        for _, d, e in score(self.rows.setdefault(category, defaultdict(list)), det, case.objects):
            if category != "flattened":
                self.conf.append((d.confidence, e))

    def summary(self, category: str) -> tuple[int, int, int, float, float, float, int, int]:
        r = self.rows[category]
        e = r["err"]
        return (
            len(r["n"]), len(r["found"]), sum(r["false"]), pct(e, 50), pct(e, 95),
            max(e) if e else float("nan"), sum(r["colour"]), len(r["colour"]),
        )  # fmt: skip


def timed(f: Callable[..., Any], *args: Any, **kwargs: Any) -> tuple[Any, float]:
    """``f(*args, **kwargs)`` and its wall time in ms."""
    t = time.perf_counter()
    out = f(*args, **kwargs)
    return out, (time.perf_counter() - t) * 1e3


def apart(a: Any, b: Any) -> tuple[float, float, int]:
    """(largest centre distance mm, largest confidence difference, object count difference) of two
    detections of one cloud, each object paired with the nearest of the other."""
    if not a.objects or not b.objects:
        return 0.0, 0.0, abs(len(a.objects) - len(b.objects))
    ca, cb = np.array([o.center for o in a.objects]), np.array([o.center for o in b.objects])
    d = np.linalg.norm(ca[:, None] - cb[None], axis=2)
    j = d.argmin(axis=1)
    conf = max(abs(o.confidence - b.objects[k].confidence) for o, k in zip(a.objects, j, strict=True))
    return float(d[np.arange(len(j)), j].max() * 1e3), float(conf), abs(len(a.objects) - len(b.objects))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--previous", type=Path, required=True, help="folder holding the previous package")
    ap.add_argument("--name", default="sofia_detector_prev", help="the previous package's name")
    ap.add_argument("--per-category", type=int, default=24)
    ap.add_argument("--repeat", type=int, default=3, help="timed calls per cloud and release")
    ap.add_argument("--cache", type=Path, default=Path("/tmp/sofia-bench-cache"))
    args = ap.parse_args()
    sys.path.insert(0, str(args.previous))
    releases = {"previous": importlib.import_module(args.name).detect, "this": detect}
    board = Board.default()
    paths = render_cases(board, args.per_category, args.cache)
    warm = load_case(paths[0], board)
    for f in releases.values():
        for _ in range(3):
            f(warm.points_base, warm.board, rgb=warm.rgb)
    tallies = {name: Tally() for name in releases}
    worst = [0.0, 0.0, 0]  # centre mm, confidence, object count
    for i, path in enumerate(paths):
        c = load_case(path, board)
        pts, rgb = c.points_base.reshape(-1, 3), c.rgb.reshape(-1, 3)
        ok = np.flatnonzero(np.isfinite(pts).all(axis=1))
        ok = ok[np.random.default_rng(0).permutation(ok.size)]
        dets: dict[str, list[Any]] = {}
        order = list(releases) if i % 2 else list(releases)[::-1]
        for _ in range(args.repeat):
            for name in order:
                det, ms = timed(releases[name], c.points_base, c.board, rgb=c.rgb)
                tallies[name].ms.setdefault(c.resolution, []).append(ms)
                dets[name] = [det]
            order.reverse()
        for name in releases:
            dets[name].append(releases[name](pts[ok], c.board, rgb=rgb[ok]))
            tallies[name].add(c.category, c, dets[name][0])
            tallies[name].add("flattened", c, dets[name][1])
        for a, b in zip(dets["this"], dets["previous"], strict=True):
            for k, v in enumerate(apart(a, b)):
                worst[k] = max(worst[k], v)
    report(tallies, worst, len(paths))


def report(tallies: dict[str, Tally], worst: list[float], n_scenes: int) -> None:
    """Print the tables and the verdicts."""
    prev, this = tallies["previous"], tallies["this"]
    print(f"\nDetector, this release against the previous one: {n_scenes} realistic scenes\n")
    print(
        "| category | release | objects | found | false | centre error p50 / p95 / max (mm) | colour right |"
    )
    print("|---|---|---|---|---|---|---|")
    bad, better = [], []  # categories worse / better than the previous release beyond the tolerances
    for cat in [*CATEGORIES, "flattened"]:
        if cat not in this.rows:
            continue
        for name, t in (("previous", prev), ("this", this)):
            n, found, false, p50, p95, mx, col, ncol = t.summary(cat)
            print(
                f"| {cat} | {name} | {n} | {found} | {false} | {p50:.2f} / {p95:.2f} / {mx:.2f} | {col}/{ncol} |"
            )
        a, b = prev.summary(cat), this.summary(cat)
        same = a[:3] == b[:3] and a[6:] == b[6:]
        moved = [
            (y - x, tol) for x, y, tol in zip(a[3:6], b[3:6], (TOL_P, TOL_P, TOL_MAX), strict=True) if x == x
        ]
        if not same or any(d > tol for d, tol in moved):
            bad.append(cat)
        elif any(-d > tol for d, tol in moved):
            better.append(cat)
    print(f"\naccuracy within tolerance (p50/p95 {TOL_P} mm, max {TOL_MAX} mm, counts and colours equal): "
          + ("met" if not bad else "MISSED in " + ", ".join(bad))
          + (f"; better by more than that in {', '.join(better)}" if better else ""))  # fmt: skip
    print(f"objects of both releases: centres at most {worst[0]:.4f} mm apart (tolerance {TOL_CENTRE}), "
          f"confidences {worst[1]:.4f} (tolerance {TOL_CONF}), object counts differ by at most {worst[2]}")  # fmt: skip
    print("\n| confidence | release | objects | within 5 mm | within 8 mm |\n|---|---|---|---|---|")
    for lo, hi in ((0.9, 1.01), (0.5, 0.9), (0.0, 0.5)):
        for name, t in (("previous", prev), ("this", this)):
            ce = np.array(t.conf).reshape(-1, 2)
            sel = ce[(ce[:, 0] >= lo) & (ce[:, 0] < hi)]
            if len(sel):
                print(f"| [{lo}, {min(hi, 1.0)}] | {name} | {len(sel)} | {np.mean(sel[:, 1] <= 5) * 100:.1f} % "
                      f"| {np.mean(sel[:, 1] <= 8) * 100:.1f} % |")  # fmt: skip
    print(
        "\n| resolution | previous median | this median | ratio | target | verdict |\n|---|---|---|---|---|---|"
    )
    for res in sorted(this.ms):
        mp, mt = float(np.median(prev.ms[res])), float(np.median(this.ms[res]))
        ok = mt <= TARGET_MS[res] and mt / mp <= TOL_RATIO
        print(f"| {res[0]}x{res[1]} | {mp:.2f} ms | {mt:.2f} ms | {mt / mp:.2f}x | <= {TARGET_MS[res]:g} ms, "
              f"<= {TOL_RATIO}x | {'met' if ok else 'MISSED'} |")  # fmt: skip


if __name__ == "__main__":
    main()
