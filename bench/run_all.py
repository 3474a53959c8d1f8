"""Run every benchmark in turn, print their output, and write the benchmarks page of the
documentation site (docs/benchmarks.md): the host, the date, the commit, and each benchmark's
output (ours against its baseline, measured in the same run).

.venv/bin/python bench/run_all.py                    # all; writes docs/benchmarks.md (`make bench`)
.venv/bin/python bench/run_all.py codec              # the ones whose name contains "codec"; page untouched
.venv/bin/python bench/run_all.py codec --out x.md   # and their page, to x.md
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
PAGE = REPO / "docs" / "benchmarks.md"
ORDER = [
    "bench_codec",
    "bench_replay",
    "bench_detector",
    "bench_detector_real",
    "bench_calibrator",
    "bench_calibrator_burst",
    "bench_gripper",
    "bench_arm",
    "bench_autocal",
    "bench_camera",
    "bench_grasp",
    "bench_transport",
    "bench_system",
    "bench_fuzz",
    "bench_memory",
]
TARGETS = """\
| benchmark | target | baseline in the same run |
|---|---|---|
| `bench_codec.py` | PointCloud2 decode without copying, encode at most one copy | a plain memory copy of the same bytes; rosbags |
| `bench_replay.py` | 640x480 clouds replayed over Zenoh, none lost at 30 Hz | a bare Zenoh put loop from memory |
| `bench_detector.py` | median ≤ 5 ms per 640x480 cloud and ≥ 10x faster; centre error p95 ≤ 5 mm, max ≤ 8 mm on ≥ 200 scenes; all objects found; 0 false objects on empty boards; non-red fields flagged | NaN removal + Open3D `segment_plane` (5 mm, 1000 it.) + height band + `cluster_dbscan` (1 cm) + mean of the largest cluster |
| `bench_calibrator.py` | 1000/1000 from no guess; RMS of the full default calibrate() within 1.1x of the Cramér-Rao bound of the true model under robot + camera noise (rigid and with a depth error); coverage of the reported 1-sigma / 2-sigma / 6-DoF region; false outliers <= 1 %; the lab's real samples; full default calibrate() time at 11 and 200 samples | scipy `fmin` on the lab's pairwise sum from the truth perturbed by 2 cm and 10°, and from a zero guess; the Cramér-Rao bound |
| `bench_calibrator_burst.py` | a burst of adds to a calibrator holding 900 samples solved once | a solve after every add |
| `bench_gripper.py` | state loop ≥ 50 Hz with one read per cycle; command round trip through Zenoh | the bus limit from the packet sizes; the direct driver call |
| `bench_grasp.py` | time to the grasp report against object width and speed, with the e-Manual's Moving semantics | when Moving falls to 0 (a driver waiting for "not moving") |
| `bench_detector_real.py` | ≥ 300 realistic D435 scenes (stereo shadows, quantization, flying pixels, fingers, dark/low/tall/cone/edge-cut objects, three colours, three resolutions): found / missed / false, centre error p95 ≤ 5 mm and max ≤ 8 mm, calibrated confidence, colours; ≥ 10x faster at every resolution | the same Open3D RANSAC + DBSCAN baseline |
| `bench_camera.py` | frame → published cloud in ≤ 1/3 frame period at 640x480, 848x480, 1280x720; CPU per frame | `rs.align` + `rs.pointcloud` + numpy conversion |
| `bench_arm.py` | flange poses ≥ 100 Hz; latency from the robot's state to the bus | the robot's own state rate and period |
| `bench_autocal.py` | poses the planner needs to reach a 1 mm translation 1-sigma; coverage of the 1-sigma reported at the stop; time of a full autonomous calibration | a fixed 12-pose pattern aimed with the true mount |
| `bench_fuzz.py` | 200 malformed payloads per key: no reply and crashes 0, memory back after | - (tried / ok / error-replied per key) |
| `bench_memory.py` | detector RSS back within 1.2x of steady after each overload | its steady RSS |
| `bench_transport.py` | the transport's floor: a bare Zenoh put -> subscriber of 4.9 MB between two processes, shared memory off / on (Zenoh's transport) / written by the publisher into a shared-memory buffer | shared memory off |
| `bench_system.py` | end to end at 30 Hz (and `--rate 90`) for 60 s: latency from the cloud stamp to a separate subscriber, detect() and the plumbing (latency - detect()) separately, frames lost, CPU per service, the replayer lazy vs `--preload`; `--seconds 600 --backlog 4` is the 10-minute soak | the frame period; a bare Zenoh put -> subscriber of the same 4.9 MB in the same run (SHM on and off); the lazy replayer |
"""


@dataclass(frozen=True)
class Result:
    """One benchmark's run: its name, what it printed (stdout and stderr), seconds and exit code."""

    name: str
    output: str
    seconds: float
    returncode: int


def run(name: str) -> Result:
    """``bench/NAME.py`` run to its end, its output shown as it comes and kept."""
    t0 = time.monotonic()
    proc = subprocess.Popen([sys.executable, str(HERE / f"{name}.py")], cwd=HERE.parent, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)  # fmt: skip
    assert proc.stdout is not None
    lines = []
    for line in proc.stdout:
        print(line, end="", flush=True)
        lines.append(line)
    return Result(name, "".join(lines), time.monotonic() - t0, proc.wait())


def host() -> dict[str, str]:
    """What the numbers depend on: the machine, its load, the commit measured."""
    cpu = next((line.split(":", 1)[1].strip() for line in _read("/proc/cpuinfo").splitlines()
                if line.startswith("model name")), platform.processor() or "unknown")  # fmt: skip
    git = ["git", "-C", str(REPO)]
    commit = subprocess.run(
        [*git, "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    dirty = subprocess.run(
        [*git, "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True
    )
    return {
        "host": platform.node(),
        "cpu": f"{cpu}, {os.cpu_count()} cores",
        "python": platform.python_version(),
        "commit": (commit or "unknown") + (" (with uncommitted changes)" if dirty.stdout.strip() else ""),
        "load": " / ".join(f"{x:.2f}" for x in os.getloadavg()),
    }


def _read(path: str) -> str:
    try:
        return Path(path).read_text()
    except OSError:
        return ""


def page(results: list[Result], start: dict[str, str], end_load: str, started: datetime.datetime) -> str:
    """The benchmarks page: the run's host, date, commit and load, the targets, each benchmark's output."""
    ran = f"{started:%Y-%m-%d %H:%M} UTC" + f", {sum(r.seconds for r in results) / 60:.0f} min"
    lines = ["# Benchmarks", "",
             "Written by `make bench` (`bench/run_all.py`); do not edit by hand. Every benchmark measures "
             "ours against its baseline in the same run, so the ratios are what count on a shared machine.",
             "", "| | |", "|---|---|", f"| run | {ran} |", f"| commit | `{start['commit']}` |",
             f"| host | {start['host']}: {start['cpu']}, Python {start['python']} |",
             f"| load average (1 / 5 / 15 min) | {start['load']} at the start, {end_load} at the end |", "",
             "## What each benchmark shows", "", TARGETS.rstrip(), ""]  # fmt: skip
    for r in results:
        verdict = "passed" if r.returncode == 0 else f"**failed** (exit {r.returncode})"
        lines += [
            f"## {r.name}.py",
            "",
            f"{r.seconds:.0f} s, {verdict}.",
            "",
            "```text",
            r.output.rstrip(),
            "```",
            "",
        ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description="Run the benchmarks and write their page.")
    p.add_argument("names", nargs="*", help="run only the benchmarks whose name contains one of these")
    p.add_argument("--out", type=Path, help=f"write the page here (default {PAGE} when all are run)")
    args = p.parse_args(argv)
    out = args.out or (None if args.names else PAGE)
    start, started = host(), datetime.datetime.now(datetime.UTC)
    results = []
    for name in ORDER:
        if args.names and not any(w in name for w in args.names):
            continue
        print(f"\n### {name}.py\n", flush=True)
        results.append(r := run(name))
        print(f"\n({name}.py took {r.seconds:.0f} s, exit {r.returncode})", flush=True)
    if out is not None:
        out.write_text(page(results, start, host()["load"], started))
        print(f"\nwrote {out}", flush=True)
    failed = [r.name for r in results if r.returncode]
    if failed:
        print(f"failed: {failed}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
