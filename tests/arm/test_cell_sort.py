"""The lab's sorting task in the simulated cell (slow: three picks): a yellow, a green and a blue
object go to their places, the purple distractor stays; refusals come before any motion."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import zenoh
from sofia_runtime.client import QueryError, ask
from sofia_runtime.zenoh_config import zenoh_config
from sofia_schemas import Board
from sofia_schemas.keys import Keys
from sofia_schemas.messages import ArmCommand, ArmResult
from sofia_schemas.sim_world import ENV_SIM_WORLD, read_world
from sofia_system.sort_step import ORDER, SORT_RGB, places

from ..conftest import SOFIA, Proc
from .conftest import start_cell


@pytest.mark.slow
@pytest.mark.timeout(1500)
def test_sort_by_colour_leaves_the_distractor(
    sofia_proc: Callable[..., Proc], robot_id: str, tmp_path: Path
) -> None:
    import subprocess

    world_file, transform = tmp_path / "world.json", tmp_path / "T.json"
    truth = json.loads(subprocess.run([SOFIA, "camera", "sim-truth", "--sim-scene", "board", "--json"],
                                      capture_output=True, text=True, timeout=120, check=True).stdout)  # fmt: skip
    transform.write_text(json.dumps({"matrix": truth["T_flange_cam"]}))
    env = {ENV_SIM_WORLD: str(world_file)}
    start_cell(sofia_proc, env, ["--sim-kind", "sort", "--sim-seed", "2"], ["--transform", str(transform)],
               ["--transform", str(transform)])  # fmt: skip
    before = read_world(world_file)
    assert before is not None and len(before.objects) == 4
    by_colour = places(Board.default())
    keys = Keys(robot_id)
    with zenoh.open(zenoh_config()) as session:
        bad = ArmCommand(command="sort_colours", places_by_colour={"yellow": (1.3, 0.0, 0.0)})  # type: ignore[arg-type]
        with pytest.raises(QueryError, match="sort_colours yellow pose 'above_place'"):
            ask(session, keys.arm_command, ArmResult, bad.model_dump_json(), timeout=60)
        cmd = ArmCommand(command="sort_colours", places_by_colour=by_colour, speed=1.0, timeout_s=1200)  # type: ignore[arg-type]
        res = ask(session, keys.arm_command, ArmResult, cmd.model_dump_json(), timeout=1300)
    lines = [p.line() for p in res.phases]
    print("\n".join(lines), json.dumps(res.details))
    assert res.ok, (res.reason, lines)
    after = read_world(world_file)
    assert after is not None
    names = {rgb: name for name, rgb in SORT_RGB.items()}
    centre = {names[o.colour]: o.centre() for o in after.objects}
    for c in ORDER:
        assert res.details["seen_error_mm"][c] <= 5.0
        assert np.linalg.norm(centre[c][:2] - np.array(by_colour[c][:2])) <= 0.005, c
    purple_before = next(o.centre() for o in before.objects if names[o.colour] == "purple")
    assert np.linalg.norm(centre["purple"] - purple_before) < 1e-3
