"""`make bench` writes the benchmarks page: bench/run_all.py runs each benchmark as its own process
and writes, to docs/benchmarks.md, the host, the date, the commit, the load, the targets table and
each benchmark's output with its time and exit code. Here it runs two stand-in benchmarks (the real
ones take half an hour)."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).parents[2]


def run_all() -> ModuleType:
    spec = importlib.util.spec_from_file_location("run_all", ROOT / "bench" / "run_all.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclass looks its module up
    spec.loader.exec_module(module)
    return module


def test_run_all_writes_the_page_with_host_date_commit_and_each_output(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    ra = run_all()
    (tmp_path / "bench_fast.py").write_text(
        "print('| case | ours | baseline | ratio |')\nprint('| a | 1.0 ms | 9.0 ms | 9.0x |')\n"
    )
    (tmp_path / "bench_broken.py").write_text("import sys\nprint('half a table')\nsys.exit(3)\n")
    monkeypatch.setattr(ra, "HERE", tmp_path)
    monkeypatch.setattr(ra, "ORDER", ["bench_fast", "bench_broken", "bench_skipped"])
    out = tmp_path / "benchmarks.md"
    assert ra.main(["fast", "broken", "--out", str(out)]) == 1  # a benchmark failed
    text = out.read_text()
    assert "| a | 1.0 ms | 9.0 ms | 9.0x |" in text and "half a table" in text
    assert "## bench_fast.py" in text and "passed" in text and "**failed** (exit 3)" in text
    assert "bench_skipped" not in text
    assert re.search(r"\| run \| \d{4}-\d\d-\d\d \d\d:\d\d UTC", text)
    assert re.search(r"\| commit \| `[0-9a-f]{7,}", text)
    assert "| host |" in text and "cores" in text and "load average" in text
    assert "| `bench_detector.py` |" in text  # the targets table
    assert "half a table" in capsys.readouterr().out  # shown as it runs, too


def test_a_subset_run_leaves_the_page_alone(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    ra = run_all()
    (tmp_path / "bench_fast.py").write_text("print('ok')\n")
    monkeypatch.setattr(ra, "HERE", tmp_path)
    monkeypatch.setattr(ra, "ORDER", ["bench_fast"])
    page = tmp_path / "page.md"
    monkeypatch.setattr(ra, "PAGE", page)
    assert ra.main(["fast"]) == 0
    assert not page.exists()
    assert ra.main([]) == 0
    assert "## bench_fast.py" in page.read_text()


def test_make_bench_runs_run_all_and_the_site_links_the_page() -> None:
    assert ".venv/bin/python bench/run_all.py" in (ROOT / "Makefile").read_text()
    assert ra_page_name() == ROOT / "docs" / "benchmarks.md"
    assert "benchmarks.md" in (ROOT / "mkdocs.yml").read_text()


def ra_page_name() -> Path:
    return Path(run_all().PAGE)
