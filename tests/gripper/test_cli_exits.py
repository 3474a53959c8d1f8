"""The gripper's answers for people: a grasp that holds nothing fails (exit 1); a command with an
unknown action is refused in one line naming the action and the ones there are."""

from __future__ import annotations

import os
import subprocess
from collections.abc import Callable

import zenoh
from sofia_schemas.keys import ENCODING_JSON, Keys

from ..conftest import SOFIA, Proc, first_reply, reply_err


def test_empty_grasp_exits_1_and_unknown_action_is_one_line(
    sofia_proc: Callable[..., Proc], session: zenoh.Session, robot_id: str
) -> None:
    proc = sofia_proc("gripper", "serve", "--emulate", "--baud", "1000000")  # nothing between the fingers
    proc.wait_for_log("gripper service ready", timeout=30)
    env = dict(os.environ, SOFIA_ROBOT=robot_id)
    r = subprocess.run([SOFIA, "gripper", "grasp"], env=env, capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and "nothing grasped" in r.stdout, (r.returncode, r.stdout, r.stderr)
    r = subprocess.run([SOFIA, "gripper", "open"], env=env, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    err = reply_err(
        first_reply(session, Keys(robot_id).gripper_command, b'{"action": "dance"}', encoding=ENCODING_JSON)
    )
    assert err.error == "PayloadError" and "(input dance)" in err.message and "'grasp'" in err.message, (
        err.message
    )
    assert "\n" not in err.message and "pydantic" not in err.message and "b'" not in err.message, err.message
