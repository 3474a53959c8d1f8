"""What each step of the detector buys: the realistic scenes detected with one step turned off at a
time, against the whole detector, in one run.

Each row turns one step off (its function replaced by what it would give when it finds nothing:
no silhouette, no circle, no parts on top, ...) and lists the categories of
``bench_detector_real.py`` whose counts, colours or centre error p50 / p95 (by more than 0.2 mm) or
max (0.5 mm) change, the release tolerance of ``bench_detector_release.py``. A step whose row is
empty changes nothing on these scenes. ``lines``: the source lines of the functions the step is.

Run: ``.venv/bin/python bench/bench_detector_steps.py`` (renders the scenes that
``bench_detector_real.py`` has not cached yet; about 3 minutes on 2 cores once they are cached).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import inspect
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np
from bench_detector_real import load_case, render_cases
from bench_detector_release import TOL_MAX, TOL_P, Tally
from sofia_detector import detect
from sofia_detector.depth import clean
from sofia_detector.objects import footprint, holes, measure, rim, silhouette
from sofia_detector.segment import organized, unorganized
from sofia_replay.synth.realism import CATEGORIES
from sofia_schemas import Board

_in_view = measure.in_view  # the step's own function, called by the stand-ins below


def _no_depth_band(obj: Any, top: float, tol: float, depth: Any = None) -> Any:
    return _in_view(obj, top, tol, None)


def _never_beside(obj: Any, top: float, tol: float, depth: Any = None) -> Any:
    return dataclasses.replace(_in_view(obj, top, tol, depth), off_board=0.0)


@dataclasses.dataclass(frozen=True)
class Step:
    """One step: its name, the (module, attribute, stand-in) replacements that turn it off, and the
    functions or modules whose lines it takes."""

    name: str
    off: tuple[tuple[Any, str, Callable[..., Any]], ...]
    code: tuple[Any, ...]

    def lines(self) -> int:
        return sum(len(inspect.getsourcelines(c)[0]) for c in self.code)


STEPS = (
    Step("flying-pixel test (organized: neighbours; flattened: voxel density)",
         ((clean, "consistent_at", lambda c, mask, delta, min_neighbours=2: mask),
          (unorganized, "dense", lambda b, voxel=0, k=0: np.ones(b.shape[1], dtype=bool))),
         (clean.consistent_at, unorganized.dense)),
    Step("pieces of one colour joined across missing depth",
         ((clean, "join_pieces", lambda labels, n, *a, **k: (labels, n)),
          (unorganized, "join_pieces", lambda labels, n, *a, **k: (labels, n))),
         (clean.join_pieces, clean.label_means)),
    Step("parts standing on an object (a bottle's neck)",
         ((organized, "_with_parts_on_top", lambda labels, n, b, obj, pieces: obj),),
         (organized._with_parts_on_top,)),
    Step("specks of mixed pixels off a top", ((footprint, "_solid", lambda obj, subset: subset),),
         (footprint._solid,)),
    Step("missing depth of the top's colour (holes)",
         ((footprint, "unseen_top", lambda obj, face, tol: np.zeros((0, 2))),), (holes,)),
    Step("round tops centred by their rim", ((footprint, "round_footprint", lambda *a: None),),
         (rim.rim_xy, rim._rim_pixels, rim.round_top, rim.round_footprint)),
    Step("an upright round side for a top out of view", ((footprint, "round_side", lambda *a: None),),
         (rim.round_side,)),
    Step("caps (balls) centred on their apex", ((footprint, "fit_top", lambda *a: None),),
         (footprint.fit_top,)),
    Step("cones placed by their flanks", ((footprint, "fit_cone_apex", lambda *a: None),),
         (footprint.fit_cone_apex,)),
    Step("slivers placed from their colour silhouette",
         ((measure, "_from_silhouettes", lambda *a: []),), (silhouette, measure._from_silhouettes)),
    Step("the band of the image only one imager sees", ((measure, "in_view", _no_depth_band),), ()),
    Step("objects beside the board dropped", ((measure, "in_view", _never_beside),), ()),
    Step("white balance on the board's white fields", ((measure, "board_white", lambda *a: None),),
         (measure.board_white,)),
    Step("shaded faces' light undone before naming", ((measure, "shaded_like_another", lambda *a: False),),
         (measure.lit_share,)),
)  # fmt: skip


def changes(base: Tally, off: Tally) -> list[str]:
    """What moved beyond the release tolerance, per category: ``cat: found 22 -> 21, p95 2.2 -> 8.3``."""
    out = []
    for cat in [*CATEGORIES, "flattened"]:
        if cat not in base.rows:
            continue
        a, b = base.summary(cat), off.summary(cat)
        said = [f"{k} {x} -> {y}" for k, x, y in zip(("objects", "found", "false"), a[:3], b[:3], strict=True)
                if x != y]  # fmt: skip
        said += [f"{k} {x:.2f} -> {y:.2f} mm" for k, x, y, tol in
                 zip(("p50", "p95", "max"), a[3:6], b[3:6], (TOL_P, TOL_P, TOL_MAX), strict=True)
                 if abs(y - x) > tol]  # fmt: skip
        if a[6] != b[6]:
            said.append(f"colours right {a[6]} -> {b[6]}")
        if said:
            out.append(f"{cat}: {', '.join(said)}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--per-category", type=int, default=24)
    ap.add_argument("--cache", type=Path, default=Path("/tmp/sofia-bench-cache"))
    args = ap.parse_args()
    board = Board.default()
    paths = render_cases(board, args.per_category, args.cache)
    base, offs = Tally(), [Tally() for _ in STEPS]
    t0 = time.perf_counter()
    for path in paths:
        c = load_case(path, board)
        pts, rgb = c.points_base.reshape(-1, 3), c.rgb.reshape(-1, 3)
        ok = np.flatnonzero(np.isfinite(pts).all(axis=1))
        ok = ok[np.random.default_rng(0).permutation(ok.size)]
        for tally, step in ((base, None), *zip(offs, STEPS, strict=True)):
            with contextlib.ExitStack() as stack:
                for module, name, stand_in in step.off if step else ():
                    stack.enter_context(mock.patch.object(module, name, stand_in))
                tally.add(c.category, c, detect(c.points_base, c.board, rgb=c.rgb))
                tally.add("flattened", c, detect(pts[ok], c.board, rgb=rgb[ok]))
    print(f"\nDetector steps, each turned off in turn: {len(paths)} realistic scenes, organized and "
          f"flattened, {time.perf_counter() - t0:.0f} s\n")  # fmt: skip
    print("| step turned off | lines | categories that move beyond the release tolerance |\n|---|---:|---|")
    for step, off in zip(STEPS, offs, strict=True):
        moved = changes(base, off)
        print(f"| {step.name} | {step.lines() or '-'} | {'; '.join(moved) if moved else 'none'} |")


if __name__ == "__main__":
    main()
