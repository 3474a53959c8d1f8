"""Bad commands get clear errors naming the value; the gripper keeps working."""

from __future__ import annotations

import pytest
from pydantic import ValidationError
from sofia_gripper import CommandError, Gripper, OutOfRange
from sofia_schemas.messages import GripperCommand as Cmd


@pytest.mark.parametrize(
    ("command", "error", "match"),
    [
        (
            Cmd(action="move", opening_mm=150.0),
            OutOfRange,
            r"move opening 150 mm is outside .*\[0\.0\d*, 99\.9\d*\] mm",
        ),
        (Cmd(action="move", opening_mm=-5.0), OutOfRange, "move opening -5 mm"),
        (Cmd(action="move", position_ticks=4000), OutOfRange, r"move position 4000 ticks .*\[1433, 2519\]"),
        (Cmd(action="move"), CommandError, "needs opening_mm or position_ticks"),
        (Cmd(action="move", opening_mm=10, position_ticks=2000), CommandError, "not both"),
        (
            Cmd(action="grasp", force_n=200.0),
            OutOfRange,
            r"grasp force 200 N is outside the allowed range \[0, 50\] N",
        ),
        (Cmd(action="grasp", force_n=5, current_ma=100), CommandError, "not both"),
        (Cmd(action="open", force_n=5), CommandError, "open takes no force_n"),
        (Cmd(action="torque"), CommandError, "enable"),
    ],
)
def test_refused_with_a_clear_message(gripper: Gripper, command: Cmd, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        gripper.execute(command)
    assert gripper.execute(Cmd(action="move", opening_mm=50.0)).ok  # still serving


@pytest.mark.parametrize(
    "fields",
    [
        {"action": "fly"},
        {"action": "move", "opening_mm": float("nan")},
        {"action": "grasp", "speed": 2.0},
        {"action": "grasp", "force_n": -1},
        {"action": "open", "timeout_s": 0},
    ],
)
def test_invalid_messages_are_rejected_by_the_schema(fields: dict[str, object]) -> None:
    with pytest.raises(ValidationError):
        Cmd.model_validate(fields)
