"""SIGTERM stops the camera service promptly (the launcher kills what takes over 8 s) while it waits
for its first frame (one unsliced wait took 5.4 s)."""

from __future__ import annotations

import signal
import time
from collections.abc import Callable

from ..conftest import Proc


def test_sigterm_stops_the_camera_within_a_few_seconds(sofia_proc: Callable[..., Proc]) -> None:
    proc = sofia_proc("camera", "serve", "--sim")
    proc.wait_for_log("camera ready", timeout=90)
    t0 = time.monotonic()
    assert proc.stop(signal.SIGTERM, timeout=8.0) == 0, proc.log()
    took = time.monotonic() - t0
    assert took < 4.5, f"camera took {took:.1f} s to stop:\n{proc.log()[-2000:]}"
    assert "camera stopping" in proc.log()
