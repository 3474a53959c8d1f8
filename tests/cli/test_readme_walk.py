"""Walking the README: every `sofia` command of its fenced blocks that needs neither running services
nor hardware runs as written, in README order, in a scratch folder laid out as after `make demo`
(``walk_dir``, see conftest), and exits 0 as the README's exit-code table says for a job that ran.

The commands that talk to running services are walked by ``test_readme_bus_walk.py`` against
`sofia up` where they need no hardware; every one is listed in ``ON_THE_BUS`` with the tests that run
it. A README command in neither list fails the first test.
"""

from __future__ import annotations

import itertools
import shlex
from pathlib import Path

from .conftest import run_sofia
from .test_readme_commands import ROOT, readme_commands

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
}


def kind(argv: list[str]) -> str:
    """``offline``, ``bus`` or ``unknown`` for ``sofia ARGV``: the longest matching command prefix."""
    for prefix in sorted([*OFFLINE, *ON_THE_BUS], key=len, reverse=True):
        if tuple(argv[: len(prefix)]) == prefix:
            return "bus" if prefix in ON_THE_BUS else "offline"
    return "unknown"


def sofia_commands() -> list[tuple[int, list[str]]]:
    return [(n, argv[1:]) for n, argv in readme_commands() if argv[0] == "sofia"]


def test_every_readme_command_is_walked_here_or_run_by_a_named_test() -> None:
    unknown = [f"README.md:{n}: sofia {shlex.join(a)}" for n, a in sofia_commands() if kind(a) == "unknown"]
    assert not unknown, "add these to OFFLINE or ON_THE_BUS:\n" + "\n".join(unknown)
    missing = [test for test in ON_THE_BUS.values() if not (ROOT / test).exists()]
    assert not missing, missing


def test_every_offline_readme_command_runs_as_written(walk_dir: Path) -> None:
    offline = [(n, a) for n, a in sofia_commands() if kind(a) == "offline"]
    assert len(offline) >= 15, offline  # 18 when written
    failed = []
    for n, argv in offline:
        r = run_sofia(walk_dir, *argv)
        if r.returncode != 0:
            failed.append(
                f"README.md:{n}: sofia {shlex.join(argv)} -> exit {r.returncode}: {r.stderr.strip()[-400:]}"
            )
    assert not failed, "\n".join(failed)
    made = [f for _, argv in offline for f in outputs(argv)]
    written = {f: written_files(walk_dir / f) for f in made}
    assert len(made) >= 7 and all(written.values()), written


def written_files(path: Path) -> list[Path]:
    """``path`` if it is a non-empty file, else the ``STEM-N.SUFFIX`` files (one plot per cloud)."""
    found = [path] if path.is_file() else sorted(path.parent.glob(f"{path.stem}-*{path.suffix}"))
    return [f for f in found if f.stat().st_size > 0]


def outputs(argv: list[str]) -> list[str]:
    """The files ``sofia ARGV`` says it writes: ``--out F``, ``--plot F``, the OUT of ``synth`` and ``convert``."""
    named = [b for a, b in itertools.pairwise(argv) if a in ("--out", "--plot")]
    if argv[0] == "synth":
        named.append(argv[2])
    if argv[:2] == ["replay", "convert"]:
        named.append(argv[3])
    return named
