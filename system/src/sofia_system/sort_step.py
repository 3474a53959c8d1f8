"""The demo's sorting step in the simulated cell: a yellow, a green and a blue object and a purple
distractor on the board's first two rows (``camera serve --sim-kind sort``); the arm sorts the
three colours onto the free last row (``sort_colours``), the distractor must stay where it was.

Measured: each colour's distance from its place as the camera sees it at the end and as the
simulated world has it, the distractor's displacement (world), the time and errors per pick.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import zenoh
from sofia_runtime.client import QueryError
from sofia_schemas import Board, Keys
from sofia_schemas.messages import ArmCommand, ArmResult
from sofia_schemas.sim_world import read_world

from .summary import Summary, say

ORDER = ("yellow", "green", "blue")
PLACE_FIELDS = ((2, 0), (2, 1), (2, 2))  # the last row is free in the sort scene
SORT_RGB = {"yellow": (230, 200, 40), "green": (40, 160, 60), "blue": (30, 80, 200), "purple": (150, 60, 170)}
TOL_MM = 5.0
DISTRACTOR_TOL_MM = 1.0


def places(board: Board) -> dict[str, tuple[float, float, float]]:
    """Colour -> the centre of its field on the last row, on the board's surface (base frame)."""
    out: dict[str, tuple[float, float, float]] = {}
    for colour, fld in zip(ORDER, PLACE_FIELDS, strict=True):
        x, y, z = (float(v) for v in board.field_center_base(*fld))
        out[colour] = (x, y, z)
    return out


def _world_centres(world_file: Path) -> dict[str, np.ndarray]:
    state = read_world(world_file)
    assert state is not None, f"no simulated world in {world_file}"
    names = {rgb: name for name, rgb in SORT_RGB.items()}
    return {names[o.colour]: o.centre() for o in state.objects if o.colour in names}


def sort_step(session: zenoh.Session, keys: Keys, board: Board, world_file: Path, speed: float,
              ask_arm: Callable[[zenoh.Session, Keys, ArmCommand], ArmResult], summary: Summary) -> None:  # fmt: skip
    """Run ``sort_colours`` and add its line to the summary."""
    before = _world_centres(world_file)
    by_colour = places(board)
    say(f"sort by colour: {', '.join(f'{c} -> {np.round(p, 3).tolist()}' for c, p in by_colour.items())}, "
        "the purple distractor stays ...")  # fmt: skip
    t0 = time.monotonic()
    try:
        res = ask_arm(session, keys, ArmCommand(command="sort_colours", places_by_colour=by_colour, speed=speed,  # type: ignore[arg-type]
                                                timeout_s=1200))  # fmt: skip
    except QueryError as e:
        summary.add("sort by colour", str(e), False)
        return
    after = _world_centres(world_file)
    world_mm = {c: 1e3 * float(np.linalg.norm(after[c][:2] - np.array(by_colour[c][:2]))) if c in after else np.inf
                for c in ORDER}  # fmt: skip
    distractor_mm = (1e3 * float(np.linalg.norm(after["purple"] - before["purple"]))
                     if "purple" in after and "purple" in before else np.inf)  # fmt: skip
    seen = res.details.get("seen_error_mm", {})
    picks = res.details.get("sorted", [])
    times = ", ".join(f"{p['colour']} {p.get('duration_s', '?')} s" for p in picks)
    errors = [f"{p['colour']}: {p['error']}" for p in picks if p.get("error")]
    ok = (res.ok and all(seen.get(c, np.inf) <= TOL_MM and world_mm[c] <= TOL_MM for c in ORDER)
          and distractor_mm <= DISTRACTOR_TOL_MM)  # fmt: skip
    seen_text = ", ".join(f"{c} {seen.get(c, np.inf):.1f} mm" for c in ORDER)
    text = (f"seen at the places: {seen_text} "
            f"(world: {', '.join(f'{world_mm[c]:.1f}' for c in ORDER)} mm); distractor moved {distractor_mm:.2f} mm; "
            f"picks: {times}; {time.monotonic() - t0:.0f} s; errors: {'; '.join(errors) or res.reason or 'none'}")  # fmt: skip
    summary.add("sort by colour", text, ok)
