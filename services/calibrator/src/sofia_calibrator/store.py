"""The calibrator's samples and their append-only log (JSON lines), replayed on restart."""

from __future__ import annotations

import json
import logging
import os
from pathlib import Path

import numpy as np
from sofia_schemas.messages.calibration import CalibrationSample
from sofia_schemas.transforms import make_transform

log = logging.getLogger(__name__)
LOG_NAME = "samples.jsonl"


class SampleStore:
    """Samples by id; every change is appended (and fsynced) to ``state_dir/samples.jsonl``."""

    def __init__(self, state_dir: str | Path) -> None:
        self.dir = Path(state_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.path = self.dir / LOG_NAME
        self.samples: dict[int, CalibrationSample] = {}
        self.next_id = 0
        self._replay()
        self._file = self.path.open("a")

    def _replay(self) -> None:
        if not self.path.exists():
            return
        for i, line in enumerate(self.path.read_text().splitlines(), start=1):
            if not line.strip():
                continue
            try:
                self._apply(json.loads(line))
            except (ValueError, KeyError, TypeError) as e:  # a line cut by a crash mid-write
                log.warning("%s:%d skipped (unreadable: %s)", self.path, i, e)
        log.info("resumed %d samples from %s", len(self.samples), self.path)

    def _apply(self, entry: dict[str, object]) -> None:
        op = entry["op"]
        if op == "add":
            s = CalibrationSample.model_validate(entry["sample"])
            assert s.sample_id is not None
            self.samples[s.sample_id] = s
            self.next_id = max(self.next_id, s.sample_id + 1)
        elif op == "remove":
            self.samples.pop(int(entry["sample_id"]), None)  # type: ignore[call-overload]
        elif op == "reset":
            self.samples.clear()
        else:
            raise ValueError(f"unknown op {op!r}")

    def _append(self, entry: dict[str, object]) -> None:
        self._file.write(json.dumps(entry) + "\n")
        self._file.flush()
        os.fsync(self._file.fileno())

    def add(self, sample: CalibrationSample) -> CalibrationSample:
        s = sample.model_copy(update={"sample_id": self.next_id})
        self._append({"op": "add", "sample": s.model_dump(mode="json")})
        self._apply({"op": "add", "sample": s.model_dump(mode="json")})
        return s

    def remove(self, sample_id: int) -> None:
        if sample_id not in self.samples:
            raise KeyError(f"no sample with id {sample_id} (ids: {sorted(self.samples)})")
        self._append({"op": "remove", "sample_id": sample_id})
        self._apply({"op": "remove", "sample_id": sample_id})

    def reset(self) -> None:
        self._append({"op": "reset"})
        self._apply({"op": "reset"})

    def ordered(self) -> list[CalibrationSample]:
        return [self.samples[k] for k in sorted(self.samples)]

    def arrays(self) -> tuple[np.ndarray, np.ndarray, list[int]]:
        """(p_cam (n, 3), T_base_flange (n, 4, 4), sample ids) in id order."""
        s = self.ordered()
        if not s:
            return np.zeros((0, 3)), np.zeros((0, 4, 4)), []
        p = np.array([x.p_cam for x in s])
        T = make_transform(np.array([x.translation for x in s]), np.array([x.rotation_xyzw for x in s]))
        return p, T.reshape(-1, 4, 4), [int(x.sample_id or 0) for x in s]

    def close(self) -> None:
        self._file.close()
