"""`sofia gripper calibrate`: positions read from the servo by hand-guided steps, saved to YAML."""

from __future__ import annotations

import subprocess
import threading
from pathlib import Path

import pytest
from sofia_gripper import ConfigError, Emulator, load_config
from sofia_gripper.calibrate import calibrate
from sofia_gripper.force import calibrate_force, parse_reading

from ..conftest import SOFIA
from .conftest import BAUD, make_config


def test_calibrate_records_open_and_closed(emulator: Emulator, tmp_path: Path) -> None:
    out = tmp_path / "gripper.yaml"
    hand = iter([1500.0, 2450.0])  # where the user's hand puts the fingers at each prompt

    def ask(prompt: str) -> str:
        assert emulator.servo.get("torque_enable") == 0  # fingers free to move
        emulator.servo.position = next(hand)
        return ""

    said: list[str] = []
    new = calibrate(make_config(emulator.path), out, ask=ask, say=said.append)
    assert (new.open_ticks, new.closed_ticks) == (1500, 2450)
    saved = load_config(out)
    assert saved == new and saved.port == emulator.path
    assert any("saved" in line for line in said)


def test_calibrate_refuses_reversed_or_unmoved(emulator: Emulator, tmp_path: Path) -> None:
    positions = iter([2400.0, 1500.0])
    with pytest.raises(ConfigError, match="Drive Mode"):
        calibrate(make_config(emulator.path), tmp_path / "a.yaml", ask=lambda _: setattr(
            emulator.servo, "position", next(positions)) or "", say=lambda _: None)  # fmt: skip
    with pytest.raises(ConfigError, match="too close"):
        calibrate(make_config(emulator.path), tmp_path / "b.yaml", ask=lambda _: "", say=lambda _: None)
    assert not (tmp_path / "a.yaml").exists() and not (tmp_path / "b.yaml").exists()


def test_calibrate_command_line(emulator: Emulator, tmp_path: Path) -> None:
    out = tmp_path / "cli.yaml"
    proc = subprocess.Popen(
        [SOFIA, "gripper", "calibrate", "--port", emulator.path, "--baud", str(BAUD), "--out", str(out)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    assert proc.stdout and proc.stdin

    def answer() -> None:
        for position in (1450.0, 2500.0):
            buf = ""
            while "press Enter" not in buf:
                buf += proc.stdout.read(1)  # type: ignore[union-attr]
            emulator.servo.position = position
            proc.stdin.write("\n")  # type: ignore[union-attr]
            proc.stdin.flush()  # type: ignore[union-attr]

    t = threading.Thread(target=answer, daemon=True)
    t.start()
    t.join(30)
    assert proc.wait(30) == 0, proc.stderr.read() if proc.stderr else ""
    conf = load_config(out)
    assert (conf.open_ticks, conf.closed_ticks) == (1450, 2500)


def test_force_calibration_fits_the_scale(emulator: Emulator, tmp_path: Path) -> None:
    """`sofia gripper calibrate --force`: grasps at several currents, reads a scale, fits N/A."""
    emulator.set_object(45.0)
    k_true = 31.0  # N per A at the fingertips of this (emulated) gripper
    prompts: list[str] = []

    def scale(prompt: str) -> str:  # the scale reads the true force of the squeezing motor
        prompts.append(prompt)
        grams = k_true * emulator.snapshot()["current_ma"] / 1000 / 9.80665 * 1000
        return f"{grams:.0f} g"

    out = tmp_path / "gripper.yaml"
    new = calibrate_force(make_config(emulator.path), out, [300.0, 600.0], ask=scale, say=lambda _s: None)
    assert new.force_per_amp_n == pytest.approx(k_true, rel=0.03)
    assert load_config(out).force_per_amp_n == pytest.approx(new.force_per_amp_n)
    assert len(prompts) == 3 and "300 mA" in prompts[1]
    assert parse_reading("1.5 kg") == pytest.approx(14.71, abs=0.01) and parse_reading("12 N") == 12.0
    with pytest.raises(ConfigError, match="'heavy' is not a number"):
        parse_reading("heavy")
