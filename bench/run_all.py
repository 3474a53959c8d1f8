"""Run every benchmark in turn and print their tables (for the README's numbers).

.venv/bin/python bench/run_all.py            # all
.venv/bin/python bench/run_all.py codec      # the ones whose name contains "codec"
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
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


def main() -> int:
    wanted = sys.argv[1:]
    failed = []
    for name in ORDER:
        if wanted and not any(w in name for w in wanted):
            continue
        print(f"\n### {name}.py\n", flush=True)
        t0 = time.monotonic()
        r = subprocess.run([sys.executable, str(HERE / f"{name}.py")], cwd=HERE.parent)
        print(f"\n({name}.py took {time.monotonic() - t0:.0f} s, exit {r.returncode})", flush=True)
        if r.returncode:
            failed.append(name)
    if failed:
        print(f"failed: {failed}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
