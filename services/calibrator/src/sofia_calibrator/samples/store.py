"""The calibrator's samples, kept in an SQLite database (``samples.db``, see :mod:`.db`).

Every acknowledged change (add, remove, reset) is one committed transaction; a failed write shows in
:meth:`SampleStore.problems` until a write succeeds. Ids are never given twice: ``AUTOINCREMENT``,
and a bound reserved in ``samples.db.ids`` (a block at a time) should the database be lost. A JSONL
log of an older version (``samples.jsonl``) is imported once, then renamed ``.imported``. A damaged
database is kept aside, what could be read from it loaded, and noted in the status until a reset.
"""

from __future__ import annotations

import json
import logging
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError
from sofia_schemas.messages.calibration import CalibrationSample
from sofia_schemas.transforms import make_transform

from .checks import check_sample
from .db import SampleDb
from .durable import write_atomic
from .errors import MAX_SAMPLES, ImplausibleSample, SampleLogError, TooManySamples, UnknownSamples
from .jsonl import JsonlLog, short
from .log import Damaged

log = logging.getLogger(__name__)
DB_NAME = "samples.db"
LOG_NAME = "samples.jsonl"  # the log of older versions, imported once
IMPORTED_SUFFIX = ".imported"
IDS_NAME = "samples.db.ids"  # ids below this number may have been given: survives the database's loss
IDS_BLOCK = 1000  # ids reserved at a time (one small atomic write per block)

PAGE_MAX = 500  # samples per reply of ``samples`` (about 200 kB); ask the next page with after_id


class SamplesPage(BaseModel):
    """Payload of ``calibrator/samples`` (optional): the samples with ids above ``after_id``, at
    most ``limit`` of them, in id order."""

    model_config = ConfigDict(extra="forbid")
    after_id: int = -1
    limit: int = Field(PAGE_MAX, ge=1, le=PAGE_MAX)


class SampleStore:
    """Samples by id, mirrored from ``state_dir/samples.db``.

    ``generation`` grows with every change, so a result can be matched to the samples it used.
    """

    def __init__(self, state_dir: str | Path, max_samples: int = MAX_SAMPLES) -> None:
        if max_samples < 1:
            raise ValueError(f"max_samples must be >= 1, got {max_samples}")
        self.max_samples = max_samples
        self.refused_full = 0  # adds refused at the maximum
        self.dir = Path(state_dir)
        self.path = self.dir / DB_NAME
        self.samples: dict[int, CalibrationSample] = {}
        self.generation = 0
        self.damaged: list[Damaged] = []  # lines of an imported JSONL log that were skipped
        self.recent: list[Damaged] = []  # ... after its last reset
        self.unchecked = self.torn_bytes = self.write_errors = self.damaged_rows = 0
        self.write_failure = ""  # why the last write failed, until one succeeds
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise SampleLogError(self.path, f"cannot open the sample database: {e.strerror or e}") from None
        first_start = not self.path.exists()
        self.ids_path = self.dir / IDS_NAME
        self.reserved = self._read_reserved()
        self.db = SampleDb(self.path)
        opened = self.db.opened
        if opened.corrupt:
            self._restore(opened.salvaged, max(opened.next_id, self.reserved))
            self.db.note(f"the sample database failed its integrity check ({short(opened.corrupt)}): kept "
                         f"aside as {opened.kept_aside}, {len(opened.salvaged)} rows read back from it")  # fmt: skip
        elif first_start and (self.dir / LOG_NAME).is_file():
            self._import(self.dir / LOG_NAME)
        self.notes = self.db.notes()  # kept here: the status reads them from another thread
        self._load()
        log.info("resumed %d samples from %s", len(self.samples), self.path)

    @property
    def next_id(self) -> int:
        return self.db.next_id()

    def _read_reserved(self) -> int:
        try:
            return int(json.loads(self.ids_path.read_text())["reserved_below"])
        except FileNotFoundError:
            return 0
        except (OSError, ValueError, KeyError, TypeError) as e:
            log.warning("%s unreadable (%s): ids are reserved again from the database", self.ids_path, e)
            return 0

    def _reserve(self, next_id: int) -> None:
        """Before ``next_id`` is given: make sure it lies below the reserved bound on disk."""
        if next_id < self.reserved:
            return
        reserved = next_id + IDS_BLOCK
        try:
            write_atomic(self.ids_path, json.dumps({"reserved_below": reserved}).encode())
        except OSError as e:
            raise SampleLogError(
                self.ids_path, f"ids not reserved, nothing written: {e.strerror or e}"
            ) from None
        self.reserved = reserved

    def _import(self, log_path: Path) -> None:
        old = JsonlLog(log_path).read()
        self.damaged, self.recent = old.damaged, old.recent
        self.unchecked, self.torn_bytes = old.unchecked, old.torn_bytes
        rows = [(i, s.model_dump_json()) for i, s in sorted(old.samples.items())]
        self._reserve(old.next_id)
        self.db.insert_many(rows, old.next_id)
        for text in self._jsonl_notes(log_path):
            self.db.note(text)
        os.replace(log_path, f"{log_path}{IMPORTED_SUFFIX}")
        log.info("imported %d samples from %s (renamed %s%s)", len(rows), log_path, log_path.name,
                 IMPORTED_SUFFIX)  # fmt: skip

    def _jsonl_notes(self, log_path: Path) -> list[str]:
        out = []
        suspect = [d for d in self.recent if d.op != "add"]
        if suspect:
            where = ", ".join(f"{log_path.name}:{d.number}" for d in suspect[:5])
            out.append(f"samples may be inconsistent: damaged line(s) {where} may have removed samples "
                       "(check the samples, then remove or reset)")  # fmt: skip
        lost = [d.sample_id for d in self.recent if d.sample_id is not None]
        if lost:
            out.append(f"sample(s) {lost[:10]} lost to damaged lines")
        if self.recent:
            out.append(f"{len(self.recent)} damaged line(s) skipped, copies in {log_path}.damaged")
        return out

    def _restore(self, rows: list[tuple[int, str]], next_id: int) -> None:
        """Rows read back from a damaged database: the plausible ones go into the new one."""
        good = []
        for i, body in rows:
            try:
                check_sample(CalibrationSample.model_validate_json(body))
                good.append((i, body))
            except (ValidationError, ImplausibleSample, ValueError) as e:
                self.damaged_rows += 1
                log.warning("%s: row %d of the damaged database dropped: %s", self.path, i, short(str(e)))
        next_id = max([next_id, *(i + 1 for i, _ in rows)])
        self._reserve(next_id)
        self.db.insert_many(good, next_id)

    def _load(self) -> None:
        for i, body in self.db.rows():
            try:
                s = CalibrationSample.model_validate_json(body)
                check_sample(s)
                if s.sample_id != i:
                    raise ValueError(f"row {i} holds sample_id {s.sample_id}")
            except (ValidationError, ImplausibleSample, ValueError) as e:
                self.damaged_rows += 1
                log.warning("%s: row %d skipped: %s", self.path, i, short(str(e)))
                continue
            self.samples[i] = s
        self.generation += 1

    def _written(self, work: Callable[[], object]) -> None:
        """Run one database write, keeping the failure for the status until a write succeeds."""
        try:
            work()
        except SampleLogError as e:
            self.write_errors += 1
            self.write_failure = f"{e}"
            raise
        self.write_failure = ""

    def add(self, sample: CalibrationSample) -> CalibrationSample:
        """Store ``sample`` under a new id once its transaction committed; refuse an implausible one,
        and any beyond ``max_samples`` (:class:`TooManySamples`)."""
        check_sample(sample.model_copy(update={"sample_id": None}))
        if len(self.samples) >= self.max_samples:
            self.refused_full += 1
            raise TooManySamples(self.max_samples)
        added: list[CalibrationSample] = []

        def body(new_id: int) -> str:
            added.append(sample.model_copy(update={"sample_id": new_id}))
            return added[-1].model_dump_json()

        def write() -> None:
            self._reserve(self.db.next_id())
            self.db.add(body)

        self._written(write)
        s = added[-1]
        self.samples[int(s.sample_id or 0)] = s
        self.generation += 1
        return s

    def remove(self, sample_ids: list[int]) -> None:
        """Remove every sample of ``sample_ids`` in one transaction, or none if any id is unknown."""
        ids = list(dict.fromkeys(sample_ids))
        missing = [i for i in ids if i not in self.samples]
        if missing:
            raise UnknownSamples(missing, sorted(self.samples))
        if not ids:
            return
        self._written(lambda: self.db.remove(ids))
        for i in ids:
            del self.samples[i]
        self.generation += 1

    def reset(self) -> None:
        self._written(self.db.reset)
        self.notes = []
        self.samples.clear()
        self.recent.clear()
        self.generation += 1

    def suspect(self) -> list[str]:
        """Notes saying the samples may be inconsistent (a damaged remove or reset): while there
        are any, a removed sample may be back."""
        return [n for n in self.notes if n.startswith("samples may be inconsistent")]

    def problems(self) -> list[str]:
        """What is wrong with the samples' storage, for the service's status (empty when nothing is)."""
        out = list(self.notes)
        if self.damaged_rows:
            out.append(f"{self.damaged_rows} unreadable row(s) of {self.path.name} skipped")
        if self.write_failure:
            out.append(f"sample store not writable: {self.write_failure}")
        return out

    def counters(self) -> dict[str, int]:
        return {"damaged_lines": len(self.damaged), "unchecked_lines": self.unchecked,
                "torn_bytes": self.torn_bytes, "write_errors": self.write_errors,
                "damaged_rows": self.damaged_rows, "corrupt_db": int(bool(self.db.opened.corrupt)),
                "refused_full": self.refused_full}  # fmt: skip

    def ordered(self) -> list[CalibrationSample]:
        return [self.samples[k] for k in sorted(self.samples)]

    def page(self, after_id: int = -1, limit: int = MAX_SAMPLES) -> list[CalibrationSample]:
        """At most ``limit`` samples with ids above ``after_id``, in id order."""
        ids = sorted(i for i in self.samples if i > after_id)[:limit]
        return [self.samples[i] for i in ids]

    def arrays(self) -> tuple[np.ndarray, np.ndarray, list[int]]:
        """(p_cam (n, 3), T_base_flange (n, 4, 4), sample ids) in id order."""
        s = self.ordered()
        if not s:
            return np.zeros((0, 3)), np.zeros((0, 4, 4)), []
        p = np.array([x.p_cam for x in s])
        T = make_transform(np.array([x.translation for x in s]), np.array([x.rotation_xyzw for x in s]))
        return p, T.reshape(-1, 4, 4), [int(x.sample_id or 0) for x in s]

    def close(self) -> None:
        self.db.close()
