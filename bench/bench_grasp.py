"""Grasp benchmark: time until the driver reports "grasped", against object width and speed.

The emulated MX-64 keeps Moving(122) at 1 while its profile runs, as the e-Manual says ("always
set to 1 regardless of Present Velocity while Profile is in progress"), even when the fingers
stopped on the object. Ours: the driver's stall detection (speed about 0 with the current at the
goal current, for ``stall_time_s``). Baseline, measured in the same run: the moment Moving falls
to 0, which is when a driver that waits for "not moving" could first report the grasp.

Run: ``.venv/bin/python bench/bench_grasp.py`` (about half a minute).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from sofia_gripper import Emulator, Gripper, GripperConfig
from sofia_schemas.messages import GripperCommand

BAUD = 1_000_000
WIDTHS_MM = (20.0, 40.0, 60.0, 80.0)
SPEEDS = (0.1, 0.3, 1.0)


def moving_clears(emu: Emulator, timeout_s: float) -> float:
    """Monotonic time at which the emulated servo's Moving register falls to 0."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        with emu.lock:
            emu.servo.advance(time.monotonic())
            emu.servo.refresh_registers()
            moving = emu.servo.get("moving")
        if not moving:
            return time.monotonic()
        time.sleep(0.002)
    return float("nan")


def main() -> None:
    print("Time to the grasp report (s), MX-64 emulator with e-Manual Moving semantics, 1 Mbaud\n")
    print("| object (mm) | speed | ours: stall detected | baseline: Moving falls to 0 | ours / baseline |")
    print("|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as d, Emulator(baud=BAUD, link_path=Path(d) / "tty") as emu:
        g = Gripper(GripperConfig(port=emu.path, baud=BAUD))
        g.start()
        try:
            while not g.connected:
                time.sleep(0.05)
            for width in WIDTHS_MM:
                for speed in SPEEDS:
                    emu.set_object(None)
                    assert g.execute(GripperCommand(action="open", timeout_s=30)).ok
                    emu.set_object(width)
                    t0 = time.monotonic()
                    r = g.execute(GripperCommand(action="grasp", speed=speed, timeout_s=30))
                    ours = r.duration_s
                    base = moving_clears(emu, 30.0) - t0
                    ok = "" if r.grasped else f" ({r.reason})"
                    print(f"| {width:.0f} | {speed:.1f} | {ours:.2f}{ok} | {base:.2f} | {ours / base:.2f} |")
        finally:
            g.close()


if __name__ == "__main__":
    main()
