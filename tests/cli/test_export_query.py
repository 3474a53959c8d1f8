"""The README's `--payload cloud.cdr`, made and used as a newcomer would: a synthetic recording
(`sofia synth scenes`), one cloud out of it (`sofia replay export`), sent to a running detector
(`sofia query ... --payload cloud.cdr`), each step its own process."""

from __future__ import annotations

import json
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from sofia_replay.mcap_io import iter_messages, read_truth
from sofia_schemas.keys import TOPIC_POINTS

from ..conftest import SOFIA

TIMEOUT_S = 300  # generous: the machine is shared


def sofia(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([SOFIA, *args], capture_output=True, text=True, timeout=TIMEOUT_S)


def test_export_then_query_the_detector(
    tmp_path: Path, sofia_proc: Callable[..., Any], robot_id: str
) -> None:
    detector = sofia_proc("detector", "serve")  # starts while the recording is rendered
    recording, cloud = tmp_path / "data" / "scenes.mcap", tmp_path / "cloud.cdr"
    made = sofia("synth", "scenes", str(recording), "--n-scenes", "2", "--kind", "one", "--frames", "base")
    assert made.returncode == 0, made.stderr
    assert "scenes written" in made.stderr  # progress on stderr, the file on stdout

    exported = sofia("replay", "export", str(recording), "--index", "1", "--out", str(cloud))
    assert exported.returncode == 0, exported.stderr
    assert f"{TOPIC_POINTS}[1]" in exported.stdout
    recorded = [m.data for m in iter_messages(recording, [TOPIC_POINTS])]
    assert cloud.read_bytes() == recorded[1]  # the payload exactly as recorded

    detector.wait_for_log("detector ready", timeout=TIMEOUT_S)
    key = f"sofia/{robot_id}/detector/detect"
    replied = sofia("query", key, "--payload", str(cloud), "--json", "--timeout", "60")
    assert replied.returncode == 0, (replied.stdout, replied.stderr)
    reply = json.loads(replied.stdout.splitlines()[-1])
    detection = reply["json"]
    truth = read_truth(recording)
    assert truth is not None
    frame = truth["frames"][1]
    assert detection["stamp_ns"] == frame["stamp_ns"] and detection["status"] == "ok", detection
    assert len(detection["objects"]) == len(frame["objects"]) == 1
    error_m = np.linalg.norm(np.array(detection["objects"][0]["center"]) - frame["objects"][0]["center"])
    assert error_m < 0.005, f"centre off by {error_m * 1000:.1f} mm"

    # a payload that is not a cloud: the detector answers with an error naming it, exit 1 (a failed job)
    junk = tmp_path / "junk.cdr"
    junk.write_bytes(b"not a cloud")
    refused = sofia("query", key, "--payload", str(junk), "--timeout", "60")
    assert refused.returncode == 1, (refused.stdout, refused.stderr)
    assert "error" in refused.stdout and "Traceback" not in refused.stderr
    # an index the recording does not have: exit 2, saying how many there are
    outside = sofia("replay", "export", str(recording), "--index", "5", "--out", str(tmp_path / "x.cdr"))
    assert outside.returncode == 2 and "has 2 messages on /pc_glob" in outside.stderr, outside.stderr
    assert not (tmp_path / "x.cdr").exists()
