"""Walking the docs: every `sofia` command of the fenced blocks of the README and of each page of
the documentation site that needs neither running services nor hardware runs as written, page by
page in the page's order (two at a time where neither names a file the other writes), in a scratch
folder laid out as after `make demo` (``walk_dir``, see conftest), and exits 0 as the exit-code
table says for a job that ran, writing the files it names. The how-to pages a newcomer follows with
their own data ("calibrate from your own files", "detect on your own cloud") are walked whole.

The commands that talk to running services are walked by ``test_docs_bus_walk.py`` (and the ROS 2
page by ``test_docs_ros2_walk.py``) against `sofia up` where they need no hardware; every one is
listed in ``ON_THE_BUS`` with the tests that run it. A documented command in neither list fails the
first test.
"""

from __future__ import annotations

import itertools
import shlex
import subprocess
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

import pytest

from .conftest import run_once
from .test_docs_commands import ROOT, doc_pages, page_commands

OFFLINE = [("synth",), ("replay", "export"), ("replay", "convert"), ("replay", "info"), ("detect",),
           ("calibrate",), ("camera", "sim-truth")]  # fmt: skip
ON_THE_BUS = {  # command -> the tests that run it against running services or simulated hardware
    ("calibrate", "auto"): "tests/arm/test_autocal.py",
    ("echo",): "tests/cli/test_exit_codes.py",
    ("query",): "tests/cli/test_export_query.py",
    ("health",): "tests/cli/test_exit_codes.py",
    ("up",): "tests/cli/test_up.py",
    ("replay", "play"): "tests/replay/test_play.py",
    ("gripper",): "tests/gripper/test_cli.py",
    ("arm",): "tests/arm/test_arm_service.py",
    ("camera",): "tests/camera/test_service.py",
    ("detector", "serve"): "tests/detector/test_service.py",
    ("viz",): "tests/viz/test_viz.py",
    # the calibration-targets page: your own files or other labs' data sets, not in the repository
    ("calibrate", "--setup"): "tests/calibrator/test_any_target.py",
    ("calibrate", "--target"): "tests/calibrator/test_any_target.py",
}


def kind(argv: list[str]) -> str:
    """``offline``, ``bus`` or ``unknown`` for ``sofia ARGV``: the longest matching command prefix."""
    for prefix in sorted([*OFFLINE, *ON_THE_BUS], key=len, reverse=True):
        if tuple(argv[: len(prefix)]) == prefix:
            return "bus" if prefix in ON_THE_BUS else "offline"
    return "unknown"


WALKED_WHOLE = {
    "docs/how-to/calibrate-from-files.md": 7,
    "docs/how-to/detect-your-cloud.md": 9,
}  # page: commands
WORKERS = 2  # commands of a page running at once (2 cores)


def sofia_commands(page: Path | None = None) -> list[tuple[str, list[str]]]:
    """(``page:line``, argv after `sofia`) of ``page``, or of every documented page in order."""
    found = page_commands(page) if page else [c for p in doc_pages() for c in page_commands(p)]
    return [(n, argv[1:]) for n, argv in found if argv[0] == "sofia"]


def offline_pages() -> list[str]:
    """The documented pages with commands this walk runs."""
    return [p.relative_to(ROOT).as_posix() for p in doc_pages()
            if any(kind(a) == "offline" for _, a in sofia_commands(p))]  # fmt: skip


def test_every_documented_command_is_walked_here_or_run_by_a_named_test() -> None:
    unknown = [f"{n}: sofia {shlex.join(a)}" for n, a in sofia_commands() if kind(a) == "unknown"]
    assert not unknown, "add these to OFFLINE or ON_THE_BUS:\n" + "\n".join(unknown)
    missing = [test for test in ON_THE_BUS.values() if not (ROOT / test).exists()]
    assert not missing, missing
    offline = [a for _, a in sofia_commands() if kind(a) == "offline"]
    assert len(offline) >= 30, offline  # 41 when written


def test_the_how_to_pages_for_your_own_data_are_walked_whole() -> None:
    for page, least in WALKED_WHOLE.items():
        commands = sofia_commands(ROOT / page)
        assert len(commands) >= least, (page, commands)
        assert all(kind(a) == "offline" for _, a in commands), (page, commands)
        assert page in offline_pages()


def needs(argv: list[str], before: list[str]) -> bool:
    """Whether ``sofia ARGV`` must wait for ``sofia BEFORE``, given earlier: the same command, or one
    names a file the other writes."""
    return argv == before or bool(set(outputs(before)) & set(argv) or set(outputs(argv)) & set(before))


def test_a_command_waits_for_the_commands_whose_files_it_names() -> None:
    convert = ["replay", "convert", "perception.bag", "recordings/perception.mcap"]
    assert needs(["detect", "recordings/perception.mcap"], convert)  # reads what convert writes
    assert needs(["detect", "cloud.pcd", "--plot", "board.png"], ["detect", "x.npy", "--plot", "board.png"])
    assert needs(convert, ["detect", "recordings/perception.mcap"])  # writes what the earlier one reads
    assert needs(["calibrate", "--samples", "s.csv"], ["calibrate", "--samples", "s.csv"])
    assert not needs(["calibrate", "--samples", "s.csv"], ["calibrate", "--samples", "s.json"])
    assert not needs(["detect", "recording.mcap"], convert)


Ran = subprocess.CompletedProcess[str]


def run_page(cwd: Path, commands: list[list[str]]) -> list[Ran]:
    """Run ``commands`` (each ``sofia ARGV`` once a run, see ``run_once``), ``WORKERS`` at a time: a
    command starts once every earlier one it :func:`needs` has ended. Their results, in order."""

    def after(earlier: list[Future[Ran]], argv: list[str]) -> Ran:
        for f in earlier:  # submitted before this one: already running or done, so no deadlock
            f.result()
        return run_once(cwd, *argv)

    futures: list[Future[Ran]] = []
    with ThreadPoolExecutor(WORKERS) as pool:
        for i, argv in enumerate(commands):
            earlier = [f for f, b in zip(futures, commands[:i], strict=True) if needs(argv, b)]
            futures.append(pool.submit(after, earlier, argv))
    return [f.result() for f in futures]


@pytest.mark.parametrize("page", offline_pages())
def test_every_offline_command_of_the_page_runs_as_written(page: str, walk_dir: Path) -> None:
    offline = [(n, a) for n, a in sofia_commands(ROOT / page) if kind(a) == "offline"]
    failed = []
    for (n, argv), r in zip(offline, run_page(walk_dir, [a for _, a in offline]), strict=True):
        if r.returncode != 0:
            failed.append(f"{n}: sofia {shlex.join(argv)} -> exit {r.returncode}: {r.stderr.strip()[-400:]}")
    assert not failed, "\n".join(failed)
    made = [f for _, argv in offline for f in outputs(argv)]
    written = {f: written_files(walk_dir / f) for f in made}
    assert all(written.values()), written


def written_files(path: Path) -> list[Path]:
    """``path`` if it is a non-empty file, else the ``STEM-N.SUFFIX`` files (one plot per cloud)."""
    found = [path] if path.is_file() else sorted(path.parent.glob(f"{path.stem}-*{path.suffix}"))
    return [f for f in found if f.stat().st_size > 0]


def outputs(argv: list[str]) -> list[str]:
    """The files ``sofia ARGV`` says it writes: ``--out F``, ``--plot F``, ``--yaml F``, the OUT of ``synth`` and ``convert``."""
    named = [b for a, b in itertools.pairwise(argv) if a in ("--out", "--plot", "--yaml")]
    if argv[0] == "synth":
        named.append(argv[2])
    if argv[:2] == ["replay", "convert"]:
        named.append(argv[3])
    return named
