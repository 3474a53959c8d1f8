"""SIGTERM stops the camera service within the launcher's grace (8 s; it kills what takes longer)
while it waits for its first frame: about 1 s on a quiet host, 5-6 s at load 20 on 2 cores (5.4 s
on a quiet host when the wait was one 5 s call)."""

from __future__ import annotations

import signal
import time
from collections.abc import Callable

from sofia_system.launcher import GRACE_S

from ..conftest import Proc


def test_sigterm_stops_the_camera_within_a_few_seconds(sofia_proc: Callable[..., Proc]) -> None:
    proc = sofia_proc("camera", "serve", "--sim")
    proc.wait_for_log("camera ready", timeout=90)
    t0 = time.monotonic()
    assert proc.stop(signal.SIGTERM, timeout=GRACE_S + 5.0) == 0, proc.log()
    took = time.monotonic() - t0
    assert took < GRACE_S, f"camera took {took:.1f} s to stop:\n{proc.log()[-2000:]}"
    assert "camera stopping" in proc.log()
