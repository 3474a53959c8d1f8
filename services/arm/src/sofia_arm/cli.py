"""``sofia arm ...``: the service, and commands for people."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from sofia_runtime.client import query
from sofia_runtime.output import add_json_option, emit
from sofia_runtime.zenoh_config import ZenohOptions, add_zenoh_args, zenoh_config
from sofia_schemas.keys import ENCODING_JSON, Keys, add_robot_arg, default_robot
from sofia_schemas.messages import ArmCommand, ArmResult, ArmState


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("arm", help="Franka arm: service (franky), motion commands, state")
    gs = p.add_subparsers(dest="arm_cmd", required=True, metavar="ACTION")

    s = gs.add_parser("serve", help="run the arm service")
    robot = s.add_mutually_exclusive_group(required=True)
    robot.add_argument("--robot-ip", help="the robot's FCI address (e.g. 172.16.0.2)")
    robot.add_argument("--sim", action="store_true", help="start franky-sim (MuJoCo) and connect to it")
    s.add_argument(
        "--config",
        type=Path,
        help="arm YAML/JSON config (limits, workspace box, margins; default: the built-in values)",
    )
    s.add_argument("--model", choices=("panda", "fr3"),
                   help="joint limits of this robot (default panda; fr3 with --sim: franky-sim simulates an FR3)")  # fmt: skip
    s.add_argument("--max-speed", type=float, metavar="F",
                   help="relative velocity, acceleration and jerk limit, (0, 1] (default 0.1)")  # fmt: skip
    s.add_argument("--hz", type=float, metavar="HZ", help="flange pose / joint state rate, Hz (default 200)")
    s.add_argument("--rate", type=float, dest="hz", help=argparse.SUPPRESS)  # old name of --hz
    s.add_argument("--realtime", choices=("ignore", "enforce"),
                   help="enforce: libfranka's control thread must run with real-time priority (PREEMPT_RT "
                        "kernel, rtprio for the user) or the connection fails; ignore: run without "
                        "(default ignore)")  # fmt: skip
    s.add_argument("--tool", choices=("sofia", "flange"),
                   help="the tool on the flange: sofia (fingers, fingertips 0.20 m below the flange; the "
                        "config's fingertip_offset_m, finger_half_width_m) or flange (bare) (default sofia)")  # fmt: skip
    s.add_argument(
        "--board",
        type=Path,
        dest="board_file",
        metavar="FILE",
        help="board config: its surface_z is the surface the tool keeps clear of (default: none, see --surface-z)",
    )
    s.add_argument(
        "--surface-z",
        type=float,
        metavar="Z",
        help="height of the table surface, base frame, m, without --board (default 0)",
    )
    s.add_argument("--transform", type=Path, dest="transform_file", metavar="FILE",
                   help="flange->camera transform (YAML/JSON with matrix) for the survey when no calibrator "
                        "answers (default: none)")  # fmt: skip
    s.add_argument("--sim-world", type=Path, metavar="FILE",
                   help="the simulated world's file, shared with `camera serve --sim` and the gripper emulator "
                        "(default: $SOFIA_SIM_WORLD): objects between the fingers are carried with the flange")  # fmt: skip
    add_zenoh_args(s)
    s.set_defaults(func=_serve)

    def command(name: str, help: str) -> argparse.ArgumentParser:
        a = gs.add_parser(name, help=help)
        add_zenoh_args(a)
        add_robot_arg(a)
        a.add_argument("--timeout", type=float, default=60.0, help="command timeout, s")
        add_json_option(a, "the ArmState, one object" if name == "state" else "the ArmResult, one object")
        if name not in ("state", "stop", "recover"):
            a.add_argument("--speed", type=float, default=0.1, help="relative speed, (0, 1] (default 0.1)")
        return a

    m = command("move", "move to joint positions (rad) or a flange pose (m, quaternion x y z w)")
    target = m.add_mutually_exclusive_group(required=True)
    target.add_argument("--joints", type=float, nargs=7, metavar="Q", help="7 joint positions, rad")
    target.add_argument(
        "--pose",
        type=float,
        nargs=7,
        metavar="V",
        help="flange pose, base frame: x y z in m, then quaternion qx qy qz qw",
    )
    m.set_defaults(func=_command, action="move")
    for name, help in (("home", "move to the home joint positions"), ("stop", "stop any motion now"),
                       ("recover", "reconnect and run the robot's automatic error recovery")):  # fmt: skip
        command(name, help).set_defaults(func=_command, action=name)
    pp = command("pick-place", "pick the latest detected object (pick/target) and place it")
    place = pp.add_mutually_exclusive_group(required=True)
    place.add_argument("--place", type=float, nargs=3, metavar=("X", "Y", "Z"),
                       help="flange position to place at, base frame, m")  # fmt: skip
    place.add_argument("--place-object", type=float, nargs=3, metavar=("X", "Y", "Z"),
                       help="where the object should end up: the point on the surface under its centre, "
                            "base frame, m")  # fmt: skip
    pp.set_defaults(func=_command, action="pick-place")
    so = command("sort", "pick every object of the given colours and set each down at its colour's place")
    so.add_argument("--place", nargs=4, action="append", required=True, metavar=("COLOUR", "X", "Y", "Z"),
                    help="a colour (yellow, green, blue, ...) and where its objects should end up: the point "
                         "on the surface under the object's centre, base frame, m; repeat in the order to sort")  # fmt: skip
    so.set_defaults(func=_command, action="sort")
    st = command("state", "print the arm's state")
    st.set_defaults(func=_state)


def _serve(args: argparse.Namespace) -> int:
    from sofia_schemas.sim_world import world_path

    from .config import load_config
    from .service import ServiceConfig, main

    f = args.max_speed
    model = args.model or ("fr3" if args.sim else None)  # franky-sim's MuJoCo robot is an FR3 (its limits)
    arm = load_config(args.config, model=model, max_velocity=f, max_acceleration=f, max_jerk=f,
                      state_rate_hz=args.hz, realtime=args.realtime, tool=args.tool, board_file=args.board_file,
                      surface_z=args.surface_z, transform_file=args.transform_file)  # fmt: skip
    conf = ServiceConfig(arm=arm, robot=default_robot(), zenoh=ZenohOptions.from_args(args),
                         robot_ip=args.robot_ip, sim=args.sim, sim_world=args.sim_world or world_path())  # fmt: skip
    return main(conf)


def build_command(args: argparse.Namespace) -> ArmCommand:
    fields: dict[str, Any] = {"timeout_s": args.timeout}
    if hasattr(args, "speed"):
        fields["speed"] = args.speed
    if args.action == "move" and args.joints:
        fields.update(command="move_joints", q=args.joints)
    elif args.action == "move":
        fields.update(command="move_pose", position=args.pose[:3], quaternion_xyzw=args.pose[3:])
    elif args.action == "pick-place":
        fields.update(command="pick_place", place_position=args.place, place_object=args.place_object)
    elif args.action == "sort":
        fields.update(
            command="sort_colours", places_by_colour={p[0]: [float(v) for v in p[1:]] for p in args.place}
        )
    else:
        fields["command"] = args.action
    return ArmCommand.model_validate(fields)


def _ask(args: argparse.Namespace, key: str, payload: bytes | None, timeout: float) -> tuple[int, str]:
    import zenoh

    with zenoh.open(zenoh_config(ZenohOptions.from_args(args))) as session:
        replies = query(session, key, payload, timeout=timeout, encoding=ENCODING_JSON if payload else None)
    if not replies:
        return 1, f"no arm service answered on {key}"
    reply = replies[0]
    if reply.ok is not None:
        return 0, reply.ok.payload.to_bytes().decode()
    assert reply.err is not None
    return 1, reply.err.payload.to_bytes().decode(errors="replace")


def _command(args: argparse.Namespace) -> int:
    try:
        cmd = build_command(args)
    except ValueError as e:
        print(f"sofia arm {args.action}: {e}", file=sys.stderr)
        return 2
    key = Keys(args.robot or default_robot()).arm_command
    code, text = _ask(args, key, cmd.to_json_bytes(), cmd.timeout_s + 10.0)
    if code:
        print(f"sofia arm {args.action}: {text}", file=sys.stderr)
        return code
    result = ArmResult.model_validate_json(text)
    emit(args, result, lambda: describe_result(result))
    return 0 if result.ok else 1


def _state(args: argparse.Namespace) -> int:
    """The newest ArmState (published a few times a second)."""
    import zenoh

    key = Keys(args.robot or default_robot()).arm_state
    with zenoh.open(zenoh_config(ZenohOptions.from_args(args))) as session:
        sub = session.declare_subscriber(key)
        sample = sub.recv() if args.timeout <= 0 else _recv(sub, args.timeout)
    if sample is None:
        print(f"sofia arm state: nothing published on {key} within {args.timeout:g} s", file=sys.stderr)
        return 1
    state = ArmState.model_validate_json(sample.payload.to_bytes())
    emit(args, state, lambda: describe_state(state))
    return 0 if state.mode != "error" else 1


def _recv(sub: Any, timeout: float) -> Any:
    import time

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        sample = sub.try_recv()
        if sample is not None:
            return sample
        time.sleep(0.02)
    return None


def _pose(position: object, quaternion: object) -> str:
    if position is None:
        return "unknown"
    p = ", ".join(f"{v:.4f}" for v in position)  # type: ignore[attr-defined]
    q = ", ".join(f"{v:.4f}" for v in quaternion) if quaternion is not None else "?"  # type: ignore[attr-defined]
    return f"[{p}] m, quaternion x y z w [{q}]"


def describe_result(result: ArmResult) -> str:
    """For people: the outcome, the flange pose reached and each phase of a multi-step command."""
    lines = [f"{result.command}: {result.status}" + (f" ({result.reason})" if result.reason else "")
             + f", {result.duration_s:.1f} s"]  # fmt: skip
    if result.position is not None:
        lines.append(f"  flange at {_pose(result.position, result.quaternion_xyzw)} (base frame)")
    lines += [f"  {p.line()}" for p in result.phases]
    return "\n".join(lines)


def describe_state(state: ArmState) -> str:
    """For people: connection, mode, motion, flange pose, joints and rates."""
    q = ", ".join(f"{v:.3f}" for v in state.q) if state.q is not None else "unknown"
    lines = [
        f"arm: {'connected' if state.connected else 'NOT connected'}, mode {state.mode}"
        + (f" (robot: {state.robot_mode})" if state.robot_mode else "") + (", moving" if state.moving else ""),
        f"  flange at {_pose(state.position, state.quaternion_xyzw)} (base frame)",
        f"  joints [{q}] rad",
        f"  rates: robot {state.robot_rate_hz:.0f} Hz, read {state.state_rate_hz:.0f} Hz, "
        f"published {state.publish_rate_hz:.0f} Hz",
    ]  # fmt: skip
    lines.append(f"  errors: {', '.join(state.errors) or 'none'}")
    if state.last_result is not None:
        lines.append("  last command: " + describe_result(state.last_result).replace("\n", "\n  "))
    return "\n".join(lines)
