"""The import of an older version's sample log (``samples.jsonl``) under damage: torn tails,
damaged lines of every kind, checksums, old logs without them; and the sample database's refused
and failed writes, atomic removes, impossible samples. The store is the library the service runs;
``test_calibrator_service.py`` checks the same through the running service, ``test_sample_db.py``
the database itself under damage and kills."""

from __future__ import annotations

import json
import logging
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from sofia_calibrator.fitting.simulate import make_problem
from sofia_calibrator.online import make_sample
from sofia_calibrator.samples.errors import ImplausibleSample, SampleLogError, UnknownSamples
from sofia_calibrator.samples.log import encode
from sofia_calibrator.samples.store import SampleStore
from sofia_schemas.messages.calibration import CalibrationSample

T0_NS = 1_700_000_000_000_000_000


def samples(n: int, seed: int = 3) -> list[CalibrationSample]:
    """``n`` plausible samples of a simulated calibration."""
    pr = make_problem(n, np.random.default_rng(seed))
    return [make_sample(T0_NS + k, pr.p_cam[k], pr.T_base_flange[k]) for k in range(n)]


def store_with(state: Path, n: int) -> SampleStore:
    store = SampleStore(state)
    for s in samples(n):
        store.add(s)
    return store


def add_line(k: int, s: CalibrationSample) -> bytes:
    """The log line of an older version for sample ``s`` added as id ``k``."""
    return encode({"op": "add", "sample": s.model_dump(mode="json") | {"sample_id": k}})


def write_jsonl(state: Path, n: int) -> bytes:
    """An older version's log of ``n`` samples (ids 0..n-1); its bytes."""
    data = b"".join(add_line(k, s) for k, s in enumerate(samples(n)))
    state.mkdir(parents=True, exist_ok=True)
    (state / "samples.jsonl").write_bytes(data)
    return data


def old_line(entry: dict[str, object]) -> bytes:
    """A line as logs were written before checksums."""
    return json.dumps(entry).encode() + b"\n"


def test_torn_tail_is_cut_and_kept_before_the_next_append(tmp_path: Path) -> None:
    data = write_jsonl(tmp_path, 3)
    log_path = tmp_path / "samples.jsonl"
    log_path.write_bytes(data[:-60])  # a crash in the middle of the last record
    store = SampleStore(tmp_path)
    assert sorted(store.samples) == [0, 1] and store.torn_bytes == len(data.splitlines()[-1]) + 1 - 60
    torn = (tmp_path / "samples.jsonl.torn").read_bytes()
    assert data[:-60][data[:-60].rfind(b"\n") + 1 :] in torn  # the cut bytes are kept
    assert not log_path.exists() and (tmp_path / "samples.jsonl.imported").is_file()
    new = [store.add(s) for s in samples(2, seed=4)]
    store.close()
    again = SampleStore(tmp_path)  # the samples acknowledged after the import are kept, none twice
    assert sorted(again.samples) == [0, 1, *(s.sample_id for s in new)] and [s.sample_id for s in new] == [
        2,
        3,
    ]
    assert again.damaged == [] and again.torn_bytes == 0 and again.problems() == []
    again.close()


def test_garbage_without_newline_is_cut_too(tmp_path: Path) -> None:
    write_jsonl(tmp_path, 2)
    with (tmp_path / "samples.jsonl").open("ab") as f:
        f.write(b"\x00\x00garbage")
    store = SampleStore(tmp_path)
    store.add(samples(1, seed=5)[0])
    store.close()
    assert sorted(SampleStore(tmp_path).samples) == [0, 1, 2]


def test_every_kind_of_damaged_line_is_skipped_kept_counted_and_named(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    good = [s.model_dump(mode="json") | {"sample_id": k} for k, s in enumerate(samples(4))]
    no_id = dict(good[1])
    del no_id["sample_id"]
    bad = [
        b'{"op": "add", "sample": {"stamp_ns": 1, "p_cam": [0.1, 0.2, 0.5\xff\xfe]}}\n',  # not UTF-8
        old_line({"op": "add", "sample": no_id}),  # no sample_id
        b'{"op": "remove", "sample_id": 1e999}\n',  # overflows an int
        b"[" * 100_000 + b"]" * 100_000 + b"\n",  # nesting deeper than the parser's recursion
        old_line({"op": "add", "sample": good[3] | {"rotation_xyzw": [0, 0, 0, 0]}}),  # impossible
        old_line({"op": "fly"}),
        b"{}\n",
    ]
    lines = [
        old_line({"op": "add", "sample": good[0]}),
        *bad[:4],
        old_line({"op": "add", "sample": good[2]}),
        *bad[4:],
    ]
    (tmp_path / "samples.jsonl").write_bytes(b"".join(lines))
    with caplog.at_level(logging.WARNING):
        store = SampleStore(tmp_path)
    assert sorted(store.samples) == [0, 2]  # the rest loads
    assert len(store.damaged) == len(bad) and store.counters()["damaged_lines"] == len(bad)
    for d in store.damaged:  # each named in a warning with its file and line
        assert f"{tmp_path / 'samples.jsonl'}:{d.number} skipped" in caplog.text
    assert "RecursionError" in caplog.text and "sample 3 refused" in caplog.text
    side = (tmp_path / "samples.jsonl.damaged").read_bytes()
    assert all(b.rstrip(b"\n") in side for b in bad)  # every damaged line kept aside, byte for byte
    assert any("may be inconsistent" in p for p in store.problems())  # a damaged remove among them
    store.add(samples(1, seed=6)[0])  # and the log takes new samples
    store.close()


def test_damaged_remove_is_detected_by_its_checksum(tmp_path: Path) -> None:
    write_jsonl(tmp_path, 4)
    log_path = tmp_path / "samples.jsonl"
    with log_path.open("ab") as f:
        f.write(encode({"op": "remove", "sample_ids": [1]}) + add_line(4, samples(1, seed=7)[0]))
    lines = log_path.read_bytes().splitlines(keepends=True)
    assert b'"op":"remove","sample_ids":[1]' in lines[4]
    lines[4] = lines[4].replace(b"[1]", b"[2]")  # still valid JSON: only the checksum sees it
    log_path.write_bytes(b"".join(lines))
    store = SampleStore(tmp_path)
    assert sorted(store.samples) == [0, 1, 2, 3, 4] and len(store.damaged) == 1
    assert "checksum mismatch" in store.damaged[0].reason
    assert any("samples may be inconsistent" in p and "samples.jsonl:5" in p for p in store.problems())
    store.close()
    again = SampleStore(tmp_path)  # what the import found stays in the status across restarts ...
    assert any("samples may be inconsistent" in p for p in again.problems()) and again.suspect()
    again.reset()  # ... until the operator starts over: nothing before the reset matters
    assert again.problems() == [] and not again.suspect()
    again.close()


def test_damaged_last_add_keeps_its_id(tmp_path: Path) -> None:
    """An acknowledged add whose line was damaged later: its id is not given to the next sample, so a
    remove of the old id cannot delete the new one."""
    data = write_jsonl(tmp_path, 4)
    lines = data.splitlines(keepends=True)
    lines[3] = lines[3].replace(b'"confidence":1.0', b'"confidence":0.5')  # only the checksum sees it
    (tmp_path / "samples.jsonl").write_bytes(b"".join(lines))
    store = SampleStore(tmp_path)
    assert sorted(store.samples) == [0, 1, 2] and "checksum mismatch" in store.damaged[0].reason
    assert store.add(samples(1, seed=13)[0]).sample_id == 4
    with pytest.raises(UnknownSamples):
        store.remove([3])
    store.close()


def test_old_log_without_checksums_is_read_unchecked(tmp_path: Path) -> None:
    good = [s.model_dump(mode="json") | {"sample_id": k} for k, s in enumerate(samples(3))]
    old = [old_line({"op": "add", "sample": g}) for g in good] + [old_line({"op": "remove", "sample_id": 1})]
    (tmp_path / "samples.jsonl").write_bytes(b"".join(old))
    store = SampleStore(tmp_path)
    assert sorted(store.samples) == [0, 2] and store.unchecked == 4 and store.damaged == []
    store.add(samples(1, seed=8)[0])
    store.close()
    again = SampleStore(tmp_path)  # imported once: the database holds them from now on
    assert sorted(again.samples) == [0, 2, 3] and again.unchecked == 0 and again.problems() == []
    again.close()


def test_remove_is_atomic_and_names_the_missing_ids(tmp_path: Path) -> None:
    store = store_with(tmp_path, 3)
    before = store.db.rows()
    with pytest.raises(UnknownSamples, match=r"no sample with id 999999, 7: nothing removed"):
        store.remove([0, 999999, 7])
    assert sorted(store.samples) == [0, 1, 2] and store.db.rows() == before
    store.remove([0, 2])
    store.close()
    assert sorted(SampleStore(tmp_path).samples) == [1]


IMPOSSIBLE: dict[str, tuple[dict[str, object], str]] = {
    "zero quaternion": ({"rotation_xyzw": (0.0, 0.0, 0.0, 0.0)}, "rotation_xyzw"),
    "quaternion of norm 1e20": ({"rotation_xyzw": (1e20, 0.0, 0.0, 0.0)}, "norm 1e+20"),
    "flange 1e300 m away": ({"translation": (1e300, 0.0, 0.0)}, "more than 5.0 m"),
    "blob 20 m away": ({"p_cam": (0.0, 0.0, 20.0)}, "more than 10.0 m"),
    "blob behind the camera": ({"p_cam": (0.0, 0.1, -0.4)}, "not in front of the camera"),
    "stamp 10**400": ({"stamp_ns": 10**400}, "401 digits"),
    "negative stamp": ({"stamp_ns": -1}, "stamp_ns -1"),
}


@pytest.mark.parametrize("case", IMPOSSIBLE)
def test_impossible_sample_is_refused_with_the_reason_and_never_written(tmp_path: Path, case: str) -> None:
    store = store_with(tmp_path, 1)
    before = store.db.rows()
    change, reason = IMPOSSIBLE[case]
    with pytest.raises(ImplausibleSample, match="new sample refused") as e:
        store.add(samples(1, seed=9)[0].model_copy(update=change))
    assert reason in str(e.value)
    assert store.db.rows() == before and sorted(store.samples) == [0] and store.next_id == 1
    store.close()


def test_failed_write_refuses_and_leaves_nothing_to_be_written_later(tmp_path: Path) -> None:
    """A real partial write: the file size limit (as a full disk) stops the transaction's write to
    the WAL in its middle; the failure shows in ``problems`` until a write succeeds."""
    store_with(tmp_path, 2).close()
    size = 2000  # less than one WAL frame (a 4 kB page): the next transaction cannot be written
    script = textwrap.dedent(f"""
        import resource
        import numpy as np
        from sofia_calibrator.online import make_sample
        from sofia_calibrator.fitting.simulate import make_problem
        from sofia_calibrator.samples.store import SampleStore
        from sofia_calibrator.samples.errors import SampleLogError
        store = SampleStore({str(tmp_path)!r})
        hard = resource.getrlimit(resource.RLIMIT_FSIZE)[1]
        resource.setrlimit(resource.RLIMIT_FSIZE, ({size} + 100, hard))
        try:
            pr = make_problem(1, np.random.default_rng(10))
            store.add(make_sample(1, pr.p_cam[0], pr.T_base_flange[0]))
        except SampleLogError as e:
            print("refused:", e)
        print("problems:", store.problems(), store.counters()["write_errors"])
        resource.setrlimit(resource.RLIMIT_FSIZE, (hard, hard))
        pr = make_problem(1, np.random.default_rng(11))
        print("added", store.add(make_sample(1, pr.p_cam[0], pr.T_base_flange[0])).sample_id)
        print("then problems:", store.problems())
        store.close()
    """)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert "refused:" in out.stdout and "samples.db: add failed, nothing written" in out.stdout, out
    assert "problems: ['sample store not writable:" in out.stdout and "] 1" in out.stdout, out
    assert "added 2" in out.stdout and "then problems: []" in out.stdout, out
    store = SampleStore(tmp_path)  # the refused sample is absent, the acknowledged one is there
    assert sorted(store.samples) == [0, 1, 2] and store.problems() == [] and store.damaged_rows == 0
    assert store.samples[2].p_cam == samples(1, seed=11)[0].p_cam
    store.close()


def test_unopenable_database_is_named_not_moved(tmp_path: Path) -> None:
    (tmp_path / "samples.db").mkdir()
    with pytest.raises(SampleLogError, match=f"{tmp_path / 'samples.db'}: cannot open the sample database"):
        SampleStore(tmp_path)
    assert (tmp_path / "samples.db").is_dir() and len(list(tmp_path.iterdir())) == 1
