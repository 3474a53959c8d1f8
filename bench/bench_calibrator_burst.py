"""Time per ``add`` at 900 samples: a burst of adds solved once, against one solve per add.

Run: .venv/bin/python bench/bench_calibrator_burst.py [--samples 900] [--adds 20]

``sofia calibrator serve`` runs in its own process on a sample log of ``--samples`` simulated
samples; a client sends ``--adds`` samples with the ``add`` query, one after the other.
Ours: the adds in a burst, then one ``result`` query (the calibrator solves once the burst is over).
Baseline, in the same run: each add followed by a ``result`` query, which waits for a solve of the
samples there are: what a calibrator that re-solves after every sample costs per add.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import numpy as np

SOFIA = str(Path(sys.executable).with_name("sofia"))
T0_NS = 1_700_000_000_000_000_000


def main() -> int:
    from sofia_calibrator.fitting.simulate import make_problem
    from sofia_calibrator.online import make_sample
    from sofia_calibrator.samples.log import encode
    from sofia_runtime.client import ask
    from sofia_runtime.zenoh_config import open_session
    from sofia_schemas.keys import Keys
    from sofia_schemas.messages import CalibrationResult
    from sofia_schemas.messages.calibration import CalibrationSamples

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=900)
    ap.add_argument("--adds", type=int, default=20)
    args = ap.parse_args()
    n, m = args.samples, args.adds
    pr = make_problem(n + 2 * m, np.random.default_rng(0))
    samples = [make_sample(T0_NS + k, pr.p_cam[k], pr.T_base_flange[k]) for k in range(n + 2 * m)]
    robot = "bench" + uuid.uuid4().hex[:8]
    keys = Keys(robot)
    with tempfile.TemporaryDirectory() as tmp:
        state = Path(tmp)
        log = [encode({"op": "add", "sample": s.model_dump(mode="json") | {"sample_id": k}})
               for k, s in enumerate(samples[:n])]  # fmt: skip
        (state / "samples.jsonl").write_bytes(b"".join(log))
        env = dict(os.environ, SOFIA_ROBOT=robot)
        with open(state / "service.log", "wb") as out:
            proc = subprocess.Popen([SOFIA, "calibrator", "serve", "--state-dir", str(state)], stdout=out,
                                    stderr=subprocess.STDOUT, env=env)  # fmt: skip
        try:
            with open_session() as session:
                t0 = time.perf_counter()
                ask(session, keys.calibrator_op("result"), CalibrationResult, timeout=120)
                first_solve_s = time.perf_counter() - t0

                def add(k: int) -> None:
                    payload = samples[k].model_dump_json()
                    ask(session, keys.calibrator_op("add"), CalibrationSamples, payload, timeout=120)

                t0 = time.perf_counter()
                for k in range(n, n + m):  # baseline: a solve after every add
                    add(k)
                    ask(session, keys.calibrator_op("result"), CalibrationResult, timeout=120)
                base_s = (time.perf_counter() - t0) / m
                t0 = time.perf_counter()
                for k in range(n + m, n + 2 * m):  # ours: the burst, then the result of all of it
                    add(k)
                adds_s = (time.perf_counter() - t0) / m
                result = ask(session, keys.calibrator_op("result"), CalibrationResult, timeout=120)
                ours_s = (time.perf_counter() - t0) / m
        finally:
            proc.terminate()
            proc.wait(10)
        solves = (state / "service.log").read_text().count("calibrator: solved with")
    print(
        f"calibrator with {n} samples, {m} adds one after the other; first solve (start) {first_solve_s:.2f} s"
    )
    print("| | per add, ms | ratio to baseline |")
    print("| --- | ---: | ---: |")
    print(f"| baseline: a solve after every add | {base_s * 1e3:.1f} | 1.00 |")
    print(
        f"| ours: burst, one solve at its end (until the result) | {ours_s * 1e3:.1f} | {ours_s / base_s:.3f} |"
    )
    print(f"| ours: the add replies alone | {adds_s * 1e3:.1f} | {adds_s / base_s:.3f} |")
    print(f"solves in the service's log: {solves} (1 at start + {m} baseline + the burst's); "
          f"final result of {result.n_samples} samples")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
