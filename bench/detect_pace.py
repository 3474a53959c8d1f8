"""``detect()`` on a recording's clouds in one process: back to back, and paced at the frame period.

The detector service runs one detection per frame and waits between frames. On this machine a
detection after a wait of one frame period takes longer than the same detection run back to back
(the caches, the branch predictors and the core's clock start cold after the wait). The service's
``detect()`` time is compared with the paced time, not with a back-to-back benchmark's.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np


def paced_detect_ms(rec: Path, period_s: float, passes: int = 3) -> dict[str, float]:
    """Median ``detect()`` wall time (ms) over the clouds of the recording ``rec`` (MCAP, the
    board's frame, the default board): ``back_to_back`` and ``paced`` (``period_s`` seconds
    between the starts of two detections), ``passes`` passes each after a first pass."""
    from sofia_detector.detect import detect
    from sofia_replay.mcap_io import iter_clouds
    from sofia_schemas import Board

    board = Board.default()
    clouds = [cloud for _, _, cloud in iter_clouds(rec)]
    for cloud in clouds:  # every kernel and code path once
        detect(cloud.xyz(), board, rgb=cloud.rgb())
    out: dict[str, float] = {}
    for name, pace in (("back_to_back", 0.0), ("paced", period_s)):
        times = []
        for _ in range(passes):
            for cloud in clouds:
                start = time.perf_counter()
                detect(cloud.xyz(), board, rgb=cloud.rgb())
                took = time.perf_counter() - start
                times.append(took)
                time.sleep(max(pace - took, 0.0))
        out[name] = float(np.median(times)) * 1e3
    return out
