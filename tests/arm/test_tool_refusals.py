"""Each refusal of the tool-aware rules through the arm service (franky-sim behind it, commands
over Zenoh and the CLI): an error reply naming the pose and the rule, and the joints unchanged."""

from __future__ import annotations

import os
import subprocess

import numpy as np
from sofia_arm.poses import solve_ik
from sofia_schemas.messages import PickTarget
from sofia_schemas.transforms import make_transform

from ..conftest import SOFIA
from .conftest import Arm

DOWN = [1.0, 0.0, 0.0, 0.0]  # fingers pointing down
# an object 4 cm high at (0.52, -0.08): fingertips at its centre, 2 cm above the table
TARGET = PickTarget(
    stamp_ns=1, object_center=(0.52, -0.08, 0.02), grasp_translation=(0.52, -0.08, 0.22),
    pregrasp_translation=(0.52, -0.08, 0.32), rotation_xyzw=(1.0, 0.0, 0.0, 0.0), yaw=0.0, opening_mm=70.0,
    fingertip_offset_m=0.2, pregrasp_height_m=0.1,
).model_dump(mode="json")  # fmt: skip


def joints_now(arm: Arm) -> np.ndarray:
    with arm.lock:
        return np.array(arm.joints[-1][1])


def test_every_refusal_names_the_pose_and_the_rule_and_nothing_moves(arm: Arm) -> None:
    q0 = joints_now(arm)
    refusals = [
        # (command fields, error class, words of the message)
        ({"command": "move_pose", "position": [0.5, 0.05, 0.09], "quaternion_xyzw": DOWN},
         "BelowSurface", "move_pose target: the fingers"),
        ({"command": "move_pose", "position": [1.1, 0.0, 0.4], "quaternion_xyzw": DOWN},
         "OutsideWorkspace", "outside the workspace box"),
        ({"command": "move_pose", "position": [0.84, 0.59, 0.85], "quaternion_xyzw": DOWN},
         "Unreachable", "not reachable"),
        ({"command": "pick_place", "target": TARGET, "place_position": [0.45, -0.25, 0.12]},
         "BelowSurface", "pick_place pose 'place' (lower): the fingers"),
        ({"command": "pick_place", "target": TARGET, "place_position": [1.2, 0.0, 0.3]},
         "OutsideWorkspace", "pick_place pose 'above_place' (move)"),
        ({"command": "pick_place", "target": TARGET, "place_position": [0.84, 0.59, 0.75]},
         "Unreachable", "pick_place pose 'above_place' (move)"),
        ({"command": "pick_place", "target": {**TARGET, "grasp_translation": [0.52, -0.08, 0.15]},
          "place_position": [0.45, -0.25, 0.25]}, "BelowSurface", "pick_place pose 'grasp' (descend)"),
        ({"command": "pick_place", "target": TARGET, "place_object": [0.45, -0.25, -0.1]},
         "TargetRefused", "below the surface"),
        ({"command": "sort_colours", "places_by_colour": {"green": [0.5, 0.1, 0.0], "yellow": [1.3, 0.0, 0.0]}},
         "OutsideWorkspace", "sort_colours yellow pose 'above_place' (move)"),
        ({"command": "sort_colours", "places_by_colour": {"blue": [0.5, 0.1, -0.15]}},
         "TargetRefused", "sort_colours place of blue [0.5, 0.1, -0.15] m is below the surface"),
        ({"command": "calibrate", "calibrate": {"blob": [0.5, 0.0, -0.2]}}, "TargetRefused",
         "calibrate blob [0.5, 0.0, -0.2] m lies 0.200 m below the surface"),
        ({"command": "calibrate", "calibrate": {"blob": [1.6, 0.0, 0.0]}}, "OutsideWorkspace",
         "calibrate blob [1.6, 0.0, 0.0] m"),
    ]  # fmt: skip
    low = solve_ik(
        make_transform(np.array([0.5, 0.05, 0.12]), np.array(DOWN)), q0
    ).q  # fingertips 8 cm in the table
    refusals.append(
        ({"command": "move_joints", "q": low.tolist()}, "BelowSurface", "move_joints target: the fingers")
    )
    for fields, error, words in refusals:
        e = arm.err(**fields)
        assert e.error == error and words in e.message, (fields["command"], e)
    np.testing.assert_allclose(joints_now(arm), q0, atol=2e-3)  # the simulator's wrist chatters ~1 mrad

    env = dict(os.environ, SOFIA_ROBOT=arm.keys.robot)
    out = subprocess.run([SOFIA, "arm", "move", "--pose", "0.5", "0.05", "0.09", *map(str, DOWN)], env=env,
                         capture_output=True, text=True, timeout=120)  # fmt: skip
    assert out.returncode == 1 and "below the surface" in out.stderr, out.stderr
    np.testing.assert_allclose(joints_now(arm), q0, atol=2e-3)
