"""`sofia arm serve --realtime enforce`: libfranka's real-time requirement, refused with the reason."""

from __future__ import annotations

import json
import os
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

from ..conftest import SOFIA, Proc


@pytest.mark.skipif(Path("/sys/kernel/realtime").exists(), reason="this kernel has real-time capabilities")
def test_realtime_enforce_without_an_rt_kernel_says_why(
    sofia_proc: Callable[..., Proc], robot_id: str
) -> None:
    """On a kernel without real-time capabilities the service does not control the robot, and its
    status says why (no silent reconnect loop)."""
    arm = sofia_proc("arm", "serve", "--sim", "--realtime", "enforce")
    arm.wait_for_log("cannot control the robot", 120)
    env = dict(os.environ, SOFIA_ROBOT=robot_id)
    out = subprocess.run(
        [SOFIA, "health", "arm", "--json"], capture_output=True, text=True, timeout=60, env=env
    )
    status = json.loads(out.stdout)
    assert out.returncode == 1 and status["state"] == "error", out.stdout + out.stderr
    assert "real-time priority required" in status["detail"], status
