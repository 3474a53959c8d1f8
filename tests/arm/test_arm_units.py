"""Units of the arm package without a robot: the clock mapping, safety rules, inverse kinematics,
the shared Panda kinematics, messages and the command line."""

from __future__ import annotations

import argparse

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sofia_arm.cli import build_command, register
from sofia_arm.clock import ClockMap
from sofia_arm.config import ArmConfig, load_config
from sofia_arm.errors import ConfigError, OutsideJointLimits, OutsideWorkspace, TargetRefused, Unreachable
from sofia_arm.safety import Safety, solve_ik
from sofia_schemas.kinematics import Q_MAX, Q_MIN, panda_fk
from sofia_schemas.messages import ArmCommand
from sofia_schemas.transforms import matrix_to_quat_xyzw, pose_gap

HOME = np.array(ArmConfig().home_q)


@given(st.integers(0, 10**12), st.lists(st.integers(0, 3_000_000), min_size=20, max_size=200))
def test_clock_recovers_the_offset_from_delayed_states(offset_ns: int, delays: list[int]) -> None:
    clock = ClockMap()
    delays[len(delays) // 2] = 0  # one state arrives without delay
    stamps = [clock.update(k * 1_000_000, k * 1_000_000 + offset_ns + d) for k, d in enumerate(delays)]
    true = [k * 1_000_000 + offset_ns for k in range(len(delays))]
    assert all(s >= t for s, t in zip(stamps, true, strict=True))  # never earlier than the truth
    assert stamps[-1] == true[-1]  # once the undelayed state was seen, exact
    assert np.all(np.diff(stamps) > 0)


def test_clock_of_a_slow_robot_stays_within_the_lag_bound_and_restarts() -> None:
    clock = ClockMap()
    received = [k * 10_000_000 for k in range(300)]  # 100 states per second of our time ...
    stamps = [clock.update(k * 1_000_000, r) for k, r in enumerate(received)]  # ... 1 ms apart on its clock
    lags = np.array(received) - np.array(stamps)
    assert lags.max() <= clock.max_lag_ns and np.all(np.diff(stamps) > 0)
    assert clock.update(0, received[-1] + 1_000_000) == received[-1] + 1_000_000  # robot restarted
    assert clock.resets == 1


def test_safety_refuses_with_the_value_and_the_rule() -> None:
    safety = Safety(ArmConfig(joint_margin_rad=0.1))
    with pytest.raises(OutsideJointLimits, match=r"joint 4 target -0.1000 rad .* margin of 0.100"):
        safety.check_joint_target(np.array([0, 0, 0, -0.1, 0, 1.5, 0]))
    with pytest.raises(OutsideWorkspace, match="outside the workspace box"):
        safety.check_joint_target(np.array([2.5, 0, 0, -1.5708, 0, 1.5708, 0.7854]))  # behind the base
    with pytest.raises(TargetRefused, match="7 values"):
        safety.check_joint_target(np.zeros(6))
    with pytest.raises(TargetRefused, match="not all finite"):
        safety.check_joint_target(np.full(7, np.nan))
    T = panda_fk(HOME)
    T[:3, 3] = [0.84, 0.59, 0.89]  # inside the box, out of reach
    with pytest.raises(Unreachable, match="not reachable"):
        safety.check_pose_target(T, HOME)
    T[2, 3] = 0.01
    with pytest.raises(OutsideWorkspace, match=r"\[0.84, 0.59, 0.01\]"):
        safety.check_pose_target(T, HOME)
    assert np.allclose(safety.check_joint_target(HOME), HOME)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-0.5, 0.5), min_size=7, max_size=7))
def test_ik_finds_the_pose_of_joint_positions_near_home(dq: list[float]) -> None:
    q_true = np.clip(HOME + np.array(dq), Q_MIN + 0.1, Q_MAX - 0.1)
    T = panda_fk(q_true)
    q = solve_ik(T, HOME, Q_MIN, Q_MAX)
    assert q is not None
    dp, dr = pose_gap(T, panda_fk(q))
    assert dp < 1e-5 and np.degrees(dr) < 1e-4


def test_config_file_and_messages(tmp_path: object) -> None:
    from pathlib import Path

    path = Path(str(tmp_path)) / "arm.yaml"
    path.write_text("model: fr3\nmax_velocity: 0.2\nworkspace_min: [0.2, -0.5, 0.1]\n")
    c = load_config(path, max_acceleration=0.3)
    assert c.model == "fr3" and c.max_velocity == 0.2 and c.max_acceleration == 0.3 and c.max_jerk == 0.1
    path.write_text("max_velocity: 2\n")
    with pytest.raises(ConfigError, match="max_velocity"):
        load_config(path)
    with pytest.raises(ValueError, match="move_pose needs position"):
        ArmCommand(command="move_pose", position=(0.5, 0, 0.3))
    with pytest.raises(ValueError, match="norm"):
        ArmCommand(command="move_pose", position=(0.5, 0, 0.3), quaternion_xyzw=(1, 1, 0, 0))


def test_people_commands_build_arm_commands() -> None:
    parser = argparse.ArgumentParser()
    register(parser.add_subparsers())
    args = parser.parse_args(
        ["arm", "move", "--joints", "0", "0", "0", "-1.5", "0", "1.5", "0.7", "--speed", "0.2"]
    )
    cmd = build_command(args)
    assert cmd.command == "move_joints" and cmd.q == (0, 0, 0, -1.5, 0, 1.5, 0.7) and cmd.speed == 0.2
    cmd = build_command(parser.parse_args(["arm", "pick-place", "--place", "0.5", "0.2", "0.3"]))
    assert cmd.command == "pick_place" and cmd.place_position == (0.5, 0.2, 0.3)
    cmd = build_command(parser.parse_args(["arm", "move", "--pose", "0.5", "0", "0.4", "1", "0", "0", "0"]))
    assert cmd.command == "move_pose" and cmd.quaternion_xyzw == (1, 0, 0, 0)
    assert build_command(parser.parse_args(["arm", "home"])).command == "home"


def test_sofia_up_runs_the_arm_when_asked() -> None:
    from sofia_system.launcher import add_up_args, default_specs

    parser = argparse.ArgumentParser()
    add_up_args(parser)
    specs = {s.name: s for s in default_specs(parser.parse_args([]))}
    assert "arm" not in specs  # the robot moves only when asked for
    specs = {s.name: s for s in default_specs(parser.parse_args(["--services", "detector,arm"]))}
    assert specs["arm"].args == ["arm", "serve", "--sim"] and specs["arm"].status == "arm"
    specs = {
        s.name: s for s in default_specs(parser.parse_args(["--services", "arm", "--robot-ip", "172.16.0.2"]))
    }
    assert specs["arm"].args == ["arm", "serve", "--robot-ip", "172.16.0.2"]


def test_the_planner_keeps_to_the_joint_limits_of_the_robot_driven() -> None:
    """An FR3 (franky-sim's robot, `arm serve --sim`) turns joint 1 less far than a Panda: a flange
    pose inside the box (pointing down) that the Panda planner reaches from the start with joint 1 at
    -2.80 rad is planned within the FR3's limits, or refused, never at -2.80."""
    from sofia_arm.poses import Reach
    from sofia_arm.poses import solve_ik as plan_ik
    from sofia_schemas.kinematics import joint_limits

    fr3_lo, fr3_hi = joint_limits("fr3")
    reach = Safety(ArmConfig(model="fr3")).planner_reach(Reach())
    np.testing.assert_allclose(reach.q_lo, fr3_lo + reach.joint_margin)
    np.testing.assert_allclose(reach.q_hi, fr3_hi - reach.joint_margin)
    q = np.array([-2.8, -0.965, 0.724, -0.707, 2.378, 0.695, 1.769])  # Panda's limits, not the FR3's
    assert np.all(q >= Q_MIN) and np.all(q <= Q_MAX) and q[0] < fr3_lo[0]
    ik = plan_ik(panda_fk(q), q, reach)
    assert not ik.ok or np.all((ik.q >= reach.q_lo) & (ik.q <= reach.q_hi)), ik.q
    panda = plan_ik(panda_fk(q), q, Reach())
    assert panda.ok and panda.q[0] < fr3_lo[0]  # the Panda's limits would have sent joint 1 past the FR3's


def test_a_saved_calibration_in_either_form_gives_the_survey_its_mount(tmp_path, session) -> None:  # type: ignore[no-untyped-def]
    """With no calibrator answering, the survey reads ``--transform``: the calibrator's saved file
    (``matrix``) or a hand-written one (``translation`` + ``quaternion_xyzw``); a bad one is refused
    in one line naming the file."""
    from sofia_arm.survey import calibration
    from sofia_schemas.keys import Keys
    from sofia_schemas.transforms import make_transform

    T = make_transform(np.array([0.05, -0.03, 0.07]), np.array([0.1, 0.2, 0.3, 0.9]) / np.sqrt(0.95))
    keys = Keys("survey-test-nobody")
    (tmp_path / "q.yaml").write_text(
        f"translation: {T[:3, 3].tolist()}\nquaternion_xyzw: {matrix_to_quat_xyzw(T[:3, :3]).tolist()}\n"
    )
    (tmp_path / "m.yaml").write_text(f"matrix: {T.tolist()}\n")
    for name in ("q.yaml", "m.yaml"):
        np.testing.assert_allclose(calibration(session, keys, tmp_path / name, timeout_s=0.2), T, atol=1e-12)
    assert calibration(session, keys, None, timeout_s=0.2) is None
    (tmp_path / "bad.yaml").write_text("matrix: [[1, 0], [0, 1]]\n")
    with pytest.raises(TargetRefused, match=r"bad\.yaml: matrix must have shape \(4, 4\)"):
        calibration(session, keys, tmp_path / "bad.yaml", timeout_s=0.2)
