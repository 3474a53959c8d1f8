"""The command line: config file + overrides, and the emulator as its own process."""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from pathlib import Path

from dynamixel_sdk import COMM_SUCCESS, PacketHandler, PortHandler
from sofia_gripper import GripperConfig, save_config
from sofia_gripper.cli import build_command, gripper_config
from sofia_runtime.cli import build_parser

from ..conftest import SOFIA, Proc
from .conftest import wait_until


def test_config_file_with_command_line_overrides(tmp_path: Path) -> None:
    path = tmp_path / "g.yaml"
    save_config(GripperConfig(port="/dev/ttyUSB3", open_ticks=1500, closed_ticks=2500), path)
    args = build_parser().parse_args(
        ["gripper", "serve", "--config", str(path), "--baud", "1000000", "--protocol", "1.0"]
    )
    conf = gripper_config(args)
    assert (conf.port, conf.baud, conf.protocol, conf.open_ticks) == ("/dev/ttyUSB3", 1_000_000, 1, 1500)


def test_people_commands_build_the_right_messages() -> None:
    parse = build_parser().parse_args
    cmd = build_command(parse(["gripper", "grasp", "--force", "15", "--speed", "0.5"]))
    assert (cmd.action, cmd.force_n, cmd.speed) == ("grasp", 15.0, 0.5)
    cmd = build_command(parse(["gripper", "move", "--opening", "42"]))
    assert (cmd.action, cmd.opening_mm) == ("move", 42.0)
    assert build_command(parse(["gripper", "torque", "off"])).enable is False


def test_emulate_command_serves_a_tty(sofia_proc: Callable[..., Proc], tmp_path: Path) -> None:
    link = tmp_path / "ttyEMU"
    proc = sofia_proc("gripper", "emulate", "--baud", "1000000", "--protocol", "1.0", "--link", str(link))
    wait_until(lambda: str(link) in proc.log(), 20.0, "tty path printed")
    port = PortHandler(str(link))
    assert port.setBaudRate(1_000_000)
    try:
        assert PacketHandler(1.0).ping(port, 1) == (310, COMM_SUCCESS, 0)
    finally:
        port.closePort()
    assert proc.stop() == 0


def test_emulator_console_injects_faults(tmp_path: Path) -> None:
    link = tmp_path / "ttyCON"
    proc = subprocess.Popen(
        [SOFIA, "gripper", "emulate", "--baud", "1000000", "--link", str(link)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    assert proc.stdin and proc.stdout
    try:
        assert proc.stdout.readline().strip() == str(link)
        port = PortHandler(str(link))
        assert port.setBaudRate(1_000_000)
        ph = PacketHandler(2.0)
        assert ph.ping(port, 1) == (311, COMM_SUCCESS, 0)
        for line in ("overload", "bogus 1"):
            proc.stdin.write(line + "\n")
            proc.stdin.flush()
        assert proc.stdout.readline().strip() == "ok: overload"
        assert proc.stdout.readline().startswith("unknown command 'bogus 1'")
        assert ph.ping(port, 1) == (311, COMM_SUCCESS, 0x80)  # alert bit: hardware error
        assert ph.read1ByteTxRx(port, 1, 70)[0] == 1 << 5  # Hardware Error Status: overload
        port.closePort()
    finally:
        proc.terminate()
        assert proc.wait(10) == 0


def test_serve_takes_the_common_options_and_every_option_has_help() -> None:
    parser = build_parser()
    args = parser.parse_args(["gripper", "serve", "--robot", "r2", "--emulate"])
    assert args.robot == "r2"
    gripper_parsers = next(
        a
        for a in parser._subparsers._group_actions[0].choices["gripper"]._actions  # type: ignore[union-attr]
        if a.dest == "gripper_cmd"
    ).choices
    assert "run" not in gripper_parsers, "`gripper run` duplicated `serve`"
    missing = [
        f"gripper {name} {a.option_strings}"
        for name, sub in gripper_parsers.items()
        for a in sub._actions
        if a.option_strings and a.dest != "help" and not a.help
    ]
    assert not missing, missing
