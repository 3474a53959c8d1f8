"""Gripper benchmark: state-loop rate vs the bus limit, command round trip via Zenoh vs direct.

1. State loop: the driver reads the state block (one Sync Read per cycle) from an MX-64
   emulator running as a separate process (``sofia gripper emulate``) as fast as it can, at
   57600 and 1,000,000 baud. Baseline: the bus limit, baud / (10 bits x bytes per cycle), from
   the instruction and status packet sizes.
2. Commands: ``state`` and a 20 mm ``move``, called on the driver directly (baseline) and sent
   as a Zenoh query to ``sofia gripper serve`` on the same emulator.

Run: ``.venv/bin/python bench/bench_gripper.py`` (about a minute).
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import zenoh
from sofia_gripper import Gripper, GripperConfig
from sofia_gripper import packets as pk
from sofia_gripper.control_table import STATE_BLOCK
from sofia_runtime.zenoh_config import zenoh_config
from sofia_schemas.keys import ENCODING_JSON, Keys
from sofia_schemas.messages import GripperCommand, GripperResult

SOFIA = str(Path(sys.executable).with_name("sofia"))
RATE_WINDOW_S = 3.0
N_STATE, N_MOVE = 200, 10


def cycle_bytes() -> int:
    """Bytes on the wire per state cycle, Protocol 2.0: Sync Read instruction + one status packet."""
    start, length = STATE_BLOCK[2]
    params = bytes([start & 0xFF, start >> 8, length & 0xFF, length >> 8, 1])
    instruction = pk.instruction_packet(2, pk.BROADCAST_ID, pk.INST_SYNC_READ, params)
    status = pk.status_packet(2, 1, 0, bytes(length))
    return len(instruction) + len(status)


def start_emulator(baud: int, link: Path) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [SOFIA, "--log-level", "WARNING", "gripper", "emulate", "--baud", str(baud), "--link", str(link)],
        stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    assert proc.stdout is not None
    proc.stdout.readline()  # the tty path: the emulator is serving
    return proc


def state_rate(baud: int, tmp: Path) -> float:
    link = tmp / f"tty{baud}"
    emu = start_emulator(baud, link)
    try:
        g = Gripper(GripperConfig(port=str(link), baud=baud, state_rate_hz=2000))
        g.start()
        time.sleep(0.5)
        n0, t0 = g.counters["cycles"], time.monotonic()
        time.sleep(RATE_WINDOW_S)
        rate = (g.counters["cycles"] - n0) / (time.monotonic() - t0)
        g.close()
        return rate
    finally:
        emu.terminate()
        emu.wait(5)


def timed(fn: object, n: int) -> float:
    """Median wall time of ``n`` calls, ms."""
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()  # type: ignore[operator]
        times.append((time.perf_counter() - t0) * 1000)
    return statistics.median(times)


def moves() -> list[GripperCommand]:
    return [GripperCommand(action="move", opening_mm=60.0 + 20.0 * (i % 2)) for i in range(N_MOVE)]


def round_trips(tmp: Path) -> dict[str, tuple[float, float]]:
    baud = 1_000_000
    link = tmp / "tty-rtt"
    emu = start_emulator(baud, link)
    out: dict[str, tuple[float, float]] = {}
    try:
        g = Gripper(GripperConfig(port=str(link), baud=baud))
        g.start()
        time.sleep(0.5)
        direct_state = timed(lambda: g.execute(GripperCommand(action="state")), N_STATE)
        it = iter(moves())
        direct_move = timed(lambda: g.execute(next(it)), N_MOVE)
        g.close()
        robot = "bench" + uuid.uuid4().hex[:8]
        env = dict(os.environ, SOFIA_ROBOT=robot)
        args = ["gripper", "serve", "--port", str(link), "--baud", str(baud)]
        service = subprocess.Popen([SOFIA, "--log-level", "WARNING", *args], env=env)
        key = Keys(robot).gripper_command
        try:
            with zenoh.open(zenoh_config()) as session:

                def send(cmd: GripperCommand) -> GripperResult:
                    replies = list(
                        session.get(key, payload=cmd.to_json_bytes(), encoding=ENCODING_JSON, timeout=10)
                    )
                    if not replies or replies[0].ok is None:
                        raise RuntimeError(f"no result for {cmd.action}")
                    return GripperResult.model_validate_json(replies[0].ok.payload.to_bytes())

                deadline = time.monotonic() + 20
                while True:
                    try:
                        send(GripperCommand(action="state"))
                        break
                    except RuntimeError:
                        if time.monotonic() > deadline:
                            raise
                        time.sleep(0.2)
                zenoh_state = timed(lambda: send(GripperCommand(action="state")), N_STATE)
                it = iter(moves())
                zenoh_move = timed(lambda: send(next(it)), N_MOVE)
        finally:
            service.terminate()
            service.wait(10)
        out["state"] = (direct_state, zenoh_state)
        out["move 20 mm"] = (direct_move, zenoh_move)
    finally:
        emu.terminate()
        emu.wait(5)
    return out


def main() -> None:
    nbytes = cycle_bytes()
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        print(
            f"State loop (one Sync Read of {STATE_BLOCK[2][1]} bytes = {nbytes} bytes on the wire per cycle)\n"
        )
        print("| baud | bus limit (Hz) | ours (Hz) | ours / limit |")
        print("|---:|---:|---:|---:|")
        for baud in (57600, 1_000_000):
            limit = baud / (10 * nbytes)
            rate = state_rate(baud, tmp)
            print(f"| {baud:,} | {limit:.0f} | {rate:.0f} | {rate / limit:.2f} |")
        print("\nCommand round trip, 1,000,000 baud (median)\n")
        print("| command | direct driver call (ms) | Zenoh query (ms) | Zenoh / direct |")
        print("|---|---:|---:|---:|")
        for name, (direct, via) in round_trips(tmp).items():
            print(f"| {name} | {direct:.3f} | {via:.3f} | {via / direct:.1f} |")


if __name__ == "__main__":
    main()
