"""``sofia gripper ...``: the service, the emulator, calibration, and commands for people."""

from __future__ import annotations

import argparse
import sys
import threading
from pathlib import Path
from typing import Any

from sofia_runtime.client import query
from sofia_runtime.output import add_command, add_group, emit
from sofia_runtime.service import StopFlag
from sofia_runtime.zenoh_config import ZenohOptions, add_zenoh_args, zenoh_config
from sofia_schemas.keys import ENCODING_JSON, Keys, add_robot_arg, default_robot
from sofia_schemas.messages import ErrorReply, GripperCommand, GripperResult

from .config import GripperConfig, load_config

ACTIONS = ("open", "close", "grasp", "move", "release", "stop", "torque", "reboot", "state")


def _add_servo_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("servo")
    g.add_argument(
        "--config",
        type=Path,
        help="gripper YAML config (see `sofia gripper calibrate`; default: the built-in MX-64 values)",
    )
    g.add_argument("--port", help="serial port (default /dev/ttyUSB0)")
    g.add_argument("--baud", type=int, metavar="BPS", help="baud rate, bit/s (default 57600)")
    g.add_argument("--id", type=int, dest="dxl_id", help="Dynamixel id, 0-252 (default 1)")
    g.add_argument(
        "--protocol", type=float, choices=(1.0, 2.0), help="Dynamixel protocol version (default 2.0)"
    )


def gripper_config(args: argparse.Namespace) -> GripperConfig:
    """The config file (if any) overridden by --port/--baud/--id/--protocol."""
    base = load_config(args.config) if args.config else GripperConfig()
    update: dict[str, Any] = {k: getattr(args, k) for k in ("port", "baud", "dxl_id") if getattr(args, k)}
    if args.protocol:
        update["protocol"] = int(args.protocol)
    return GripperConfig.model_validate({**base.model_dump(), **update})


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    gs = add_group(sub, "gripper", "MX-64 gripper: service, emulator, calibration, commands")

    s = add_command(gs, "serve", _serve, "run the gripper service")
    _add_servo_args(s)
    add_zenoh_args(s)
    add_robot_arg(s)
    s.add_argument("--emulate", action="store_true", help="run against an emulated MX-64 (its own process)")
    s.add_argument(
        "--object-width",
        type=float,
        metavar="MM",
        help="width of the emulated object, mm (--emulate; default: no object)",
    )

    e = add_command(gs, "emulate", _emulate, "run an MX-64 emulator on a pseudo-terminal (prints the tty "
                    "path; faults from stdin: object MM|none, overheat, overload, noreply on|off, corrupt "
                    "on|off, unplug, replug, clear)")  # fmt: skip
    e.add_argument(
        "--object-width", type=float, metavar="MM", help="object between the fingers, mm (default: none)"
    )
    e.add_argument(
        "--protocol",
        type=float,
        choices=(1.0, 2.0),
        default=2.0,
        help="Dynamixel protocol version, 1.0 or 2.0 (default 2.0)",
    )
    e.add_argument("--baud", type=int, default=57600, metavar="BPS", help="baud rate, bit/s (default 57600)")
    e.add_argument("--id", type=int, dest="dxl_id", default=1, help="Dynamixel id, 0-252 (default 1)")
    e.add_argument("--link", type=Path, help="also make this symlink to the tty (stable path; default: none)")
    e.add_argument(
        "--config",
        type=Path,
        help="gripper YAML config the emulated mechanism follows (default: the built-in values)",
    )
    e.add_argument("--exit-with-stdin", action="store_true", help="stop when stdin closes (the parent died)")

    c = add_command(gs, "calibrate", _calibrate,
                    "record the open and closed positions (or, with --force, current against force) "
                    "into a config")  # fmt: skip
    _add_servo_args(c)
    c.add_argument("--out", type=Path, required=True, help="config file to write")
    c.add_argument(
        "--force",
        action="store_true",
        help="calibrate the force estimate: grasp a scale at several currents and type what it reads",
    )
    c.add_argument(
        "--currents",
        type=float,
        nargs="+",
        metavar="MA",
        default=[200.0, 400.0, 600.0, 800.0],
        help="grasp currents for --force, mA (default 200 400 600 800)",
    )

    for action in ACTIONS:
        a = add_command(
            gs, action, _command, f"send a {action} command to the gripper service",
            "the GripperResult, one object",
            description=f"Send a {action} command to the gripper service. Exit 0 when it succeeded"
            + (" and an object is held" if action == "grasp" else "")
            + ", 1 when it failed" + (" or nothing was grasped" if action == "grasp" else "")
            + " or no service answered, 2 on a bad option.",
        )  # fmt: skip
        add_zenoh_args(a)
        add_robot_arg(a)
        a.add_argument("--timeout", type=float, default=10.0, help="command timeout, s (default 10)")
        if action == "grasp":
            a.add_argument(
                "--force",
                type=float,
                metavar="N",
                help="grasp force limit, newtons (default: the config's grasp current)",
            )
            a.add_argument(
                "--current",
                type=float,
                metavar="MA",
                help="grasp current limit, mA (default: the config's grasp_current_ma)",
            )
        if action in ("grasp", "move", "open", "close", "release"):
            a.add_argument("--speed", type=float, help="fraction of the max velocity, (0, 1] (default 1)")
        if action == "move":
            a.add_argument("--opening", type=float, metavar="MM", help="finger opening, mm")
            a.add_argument(
                "--ticks", type=int, help="motor position instead of an opening, ticks (4096/turn)"
            )
        if action == "torque":
            a.add_argument("enable", choices=("on", "off"), help="on: torque on; off: the motor turns freely")
        a.set_defaults(action=action)


def _serve(args: argparse.Namespace) -> int:
    from .service import ServiceConfig, main

    conf = ServiceConfig(
        gripper=gripper_config(args), robot=args.robot or default_robot(), zenoh=ZenohOptions.from_args(args),
        emulate=args.emulate, object_width_mm=args.object_width,
    )  # fmt: skip
    return main(conf)


def _emulate(args: argparse.Namespace) -> int:
    from .emulator import Emulator

    config = load_config(args.config) if args.config else None
    emu = Emulator(int(args.protocol), args.baud, args.dxl_id, args.object_width, config, link_path=args.link)  # type: ignore[arg-type]
    stop = StopFlag()
    print(emu.start(), flush=True)

    def console() -> None:  # fault injection from stdin, e.g. "overload", "object 40", "unplug"
        for line in sys.stdin:
            try:
                print(emu.control(line), flush=True)
            except ValueError as e:
                print(f"bad value in {line.strip()!r}: {e}", flush=True)
        if args.exit_with_stdin:
            stop.set()

    threading.Thread(target=console, daemon=True).start()
    stop.wait()
    emu.stop()
    return 0


def _calibrate(args: argparse.Namespace) -> int:
    from .calibrate import calibrate
    from .force import calibrate_force

    if args.force:
        calibrate_force(gripper_config(args), args.out, args.currents)
    else:
        calibrate(gripper_config(args), args.out)
    return 0


def build_command(args: argparse.Namespace) -> GripperCommand:
    fields: dict[str, Any] = {"action": args.action, "timeout_s": args.timeout}
    for arg, field in (("force", "force_n"), ("current", "current_ma"), ("speed", "speed"),
                       ("opening", "opening_mm"), ("ticks", "position_ticks")):  # fmt: skip
        if getattr(args, arg, None) is not None:
            fields[field] = getattr(args, arg)
    if args.action == "torque":
        fields["enable"] = args.enable == "on"
    return GripperCommand.model_validate(fields)


def _command(args: argparse.Namespace) -> int:
    import zenoh

    cmd = build_command(args)
    key = Keys(args.robot or default_robot()).gripper_command
    with zenoh.open(zenoh_config(ZenohOptions.from_args(args))) as session:
        # sent once, as soon as the service is discovered
        replies = query(
            session, key, cmd.to_json_bytes(), timeout=cmd.timeout_s + 5.0, encoding=ENCODING_JSON
        )
    if not replies:
        print(f"sofia gripper {args.action}: no gripper service answered on {key}", file=sys.stderr)
        return 1
    reply = replies[0]
    if reply.ok is not None:
        result = GripperResult.model_validate_json(reply.ok.payload.to_bytes())
        emit(args, result, lambda: describe_result(result))
        nothing = cmd.action == "grasp" and result.grasped is False  # a grasp must hold an object
        return 0 if result.ok and not nothing else 1
    assert reply.err is not None
    raw = reply.err.payload.to_bytes()
    try:
        message = ErrorReply.model_validate_json(raw).message
    except ValueError:
        message = raw.decode(errors="replace")
    print(f"sofia gripper {args.action}: error: {message}", file=sys.stderr)
    return 1


def describe_result(result: GripperResult) -> str:
    """One line for people, e.g. ``grasp: stalled, opening 39.1 mm, grasped, 0.36 s``."""
    parts = [f"{result.action}: {result.reason}" + ("" if result.ok else " (failed)")]
    if result.opening_mm is not None:
        parts.append(f"opening {result.opening_mm:.1f} mm")
    if result.grasped is not None:
        parts.append("grasped" if result.grasped else "nothing grasped")
    parts.append(f"{result.duration_s:.2f} s")
    text = ", ".join(parts)
    s = result.state
    if s is not None and result.action == "state":
        values = (("connected", s.connected), ("status", s.status), ("torque", "on" if s.torque_enabled else "off"),
                  ("current", _unit(s.current_ma, "mA")), ("force", _unit(s.force_n, "N")),
                  ("temperature", _unit(s.temperature_c, "C")), ("voltage", _unit(s.voltage_v, "V")),
                  ("hardware errors", ", ".join(s.hardware_error) or "none"), ("error", s.error))  # fmt: skip
        text += "".join(f"\n  {k}: {v}" for k, v in values if v is not None)
    return text


def _unit(value: float | None, unit: str) -> str | None:
    return None if value is None else f"{value:g} {unit}"
