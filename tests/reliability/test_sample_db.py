"""The calibrator's sample database (SQLite) under kills and damage: ids never given twice, SIGKILL
in the middle of transactions (nothing acknowledged lost, nothing removed back), a database cut
short or overwritten mid-file (kept aside, reported, the readable rows kept), and files saved
atomically under a full disk."""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
from sofia_calibrator.fitting.simulate import make_problem
from sofia_calibrator.online import make_sample
from sofia_calibrator.samples.store import SampleStore
from sofia_schemas.messages.calibration import CalibrationSample

T0_NS = 1_700_000_000_000_000_000


def samples(n: int, seed: int = 3) -> list[CalibrationSample]:
    pr = make_problem(n, np.random.default_rng(seed))
    return [make_sample(T0_NS + k, pr.p_cam[k], pr.T_base_flange[k]) for k in range(n)]


def test_ids_are_never_given_twice(tmp_path: Path) -> None:
    store = SampleStore(tmp_path)
    added = [store.add(s).sample_id for s in samples(3)]
    store.remove([2])  # the last one: its id must not come back
    store.close()
    store = SampleStore(tmp_path)
    assert added == [0, 1, 2] and store.add(samples(1, seed=4)[0]).sample_id == 3
    store.reset()
    assert store.add(samples(1, seed=5)[0]).sample_id == 4
    store.close()


WRITER = textwrap.dedent("""
    import sys
    import numpy as np
    from sofia_calibrator.online import make_sample
    from sofia_calibrator.fitting.simulate import make_problem
    from sofia_calibrator.samples.store import SampleStore
    store = SampleStore(sys.argv[1])
    pr = make_problem(50, np.random.default_rng(int(sys.argv[2])))
    print("ready", flush=True)
    k = 0
    while True:
        s = store.add(make_sample(1_700_000_000_000_000_000 + k, pr.p_cam[k % 50], pr.T_base_flange[k % 50]))
        print("add", s.sample_id, flush=True)
        if k % 3 == 2:
            store.remove([s.sample_id - 1])
            print("remove", s.sample_id - 1, flush=True)
        k += 1
""")


def test_sigkill_during_transactions_loses_and_resurrects_nothing(tmp_path: Path) -> None:
    """10 writers killed at random moments (adds and removes, each one transaction, fsynced)."""
    rng = random.Random(7)
    acked: set[int] = set()
    removed: set[int] = set()
    highest, seen = -1, set()
    for cycle in range(10):
        writer = subprocess.Popen([sys.executable, "-c", WRITER, str(tmp_path), str(cycle)],
                                  stdout=subprocess.PIPE, text=True)  # fmt: skip
        assert writer.stdout is not None and writer.stdout.readline() == "ready\n"
        first = writer.stdout.readline()  # at least one acknowledged add per cycle, however loaded the host
        time.sleep(rng.uniform(0.05, 0.4))
        os.kill(writer.pid, signal.SIGKILL)
        out, _ = writer.communicate(timeout=30)
        out = first + out
        in_flight_remove: set[int] = set()  # a remove after the last acknowledged add may have committed
        whole_lines = out.split("\n")[:-1]  # a last line the kill cut short was never acknowledged
        for line in whole_lines:
            op, sample_id = line.split()
            (acked if op == "add" else removed).add(int(sample_id))
            in_flight_remove = {int(sample_id) - 1} if op == "add" else set()
        store = SampleStore(tmp_path)
        assert store.db.opened.corrupt == "" and store.problems() == [], store.problems()
        stored = set(store.samples)
        lost = (acked - removed) - stored
        assert not lost - in_flight_remove, f"cycle {cycle}: acknowledged samples {lost} lost"
        removed |= lost  # the remove in flight committed
        assert not stored & removed, f"cycle {cycle}: removed samples back"
        new = stored - acked - seen  # committed, never acknowledged (the add the kill cut): allowed,
        assert all(i > highest for i in new), (cycle, new)  # but an id is never given twice
        highest, seen = max([highest, *stored, *acked]), seen | stored
        store.close()
    assert len(acked) >= 10, f"only {len(acked)} acknowledged adds in 10 cycles"


def _damaged_store(tmp_path: Path, damage: str) -> tuple[list[CalibrationSample], SampleStore]:
    store = SampleStore(tmp_path)
    originals = [store.add(s) for s in samples(60)]
    store.close()
    db = tmp_path / "samples.db"
    data = bytearray(db.read_bytes())
    assert not (tmp_path / "samples.db-wal").exists()  # checkpointed on close: all in the file
    if damage == "truncated":
        del data[len(data) // 2 :]
    else:  # one page in the middle overwritten with random bytes
        page = 4096 * (len(data) // 4096 // 2)
        data[page : page + 4096] = np.random.default_rng(11).bytes(4096)
    db.write_bytes(bytes(data))
    return originals, SampleStore(tmp_path)


def _check_damage_reported(tmp_path: Path, originals: list[CalibrationSample], store: SampleStore) -> None:
    problems = store.problems()
    assert problems, "damage not reported"
    by_id = {s.sample_id: s for s in originals}
    assert all(store.samples[i] == by_id[i] for i in store.samples)  # only genuine samples loaded
    assert len(store.samples) < len(originals)
    new = store.add(samples(1, seed=12)[0])  # the store keeps working, without reusing an id
    assert new.sample_id is not None and new.sample_id >= len(originals)
    store.close()
    again = SampleStore(tmp_path)  # reported until a reset, also after a restart
    assert problems[0] in again.problems()
    assert new.sample_id in again.samples
    again.reset()
    assert again.problems() == []
    again.close()


def test_database_cut_short_is_kept_aside_and_reported(tmp_path: Path) -> None:
    originals, store = _damaged_store(tmp_path, "truncated")
    assert store.db.opened.corrupt and store.counters()["corrupt_db"] == 1
    kept = store.db.opened.kept_aside
    assert kept is not None and kept.is_file() and kept.name.startswith("samples.db.corrupt-")
    assert any("failed its integrity check" in p and str(kept) in p for p in store.problems())
    _check_damage_reported(tmp_path, originals, store)


def test_database_overwritten_mid_file_is_detected(tmp_path: Path) -> None:
    originals, store = _damaged_store(tmp_path, "overwritten")
    assert store.db.opened.corrupt or store.damaged_rows, store.problems()
    _check_damage_reported(tmp_path, originals, store)


def test_save_is_atomic_under_a_full_disk(tmp_path: Path) -> None:
    """write_atomic with the file size limit below the new content: the old file stays whole."""
    target = tmp_path / "T_flange_cam.yaml"
    target.write_text("old: 1\\n")
    script = textwrap.dedent(f"""
        import resource
        from pathlib import Path
        from sofia_calibrator.samples.durable import write_atomic
        hard = resource.getrlimit(resource.RLIMIT_FSIZE)[1]
        resource.setrlimit(resource.RLIMIT_FSIZE, (1000, hard))
        try:
            write_atomic(Path({str(target)!r}), b"new: 2\\\\n" * 1000)
        except OSError as e:
            print("refused:", e.strerror)
        resource.setrlimit(resource.RLIMIT_FSIZE, (hard, hard))
        write_atomic(Path({str(target)!r}), b"new: 3\\\\n")
        print("written")
    """)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert "refused: File too large" in out.stdout and "written" in out.stdout, out
    assert target.read_text() == "new: 3\\n" and sorted(p.name for p in tmp_path.iterdir()) == [target.name]
