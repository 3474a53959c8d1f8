"""The exit-code table, the same for every command: 0 success, 1 the job failed, 2 a usage or input
error. Each case is a real `sofia` process; they run side by side to keep the test short."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest
from sofia_runtime import cli

from ..conftest import SOFIA

# in this process (fast): argv (with {tmp} and {robot} filled in), exit code, text the error must contain
IN_PROCESS: list[tuple[list[str], int, str]] = [
    # usage errors: argparse's own, or a value the command refuses
    (["no-such-command"], 2, "invalid choice"),
    (["replay", "play"], 2, "the following arguments are required: file"),
    (["synth", "scenes", "{tmp}/o.mcap", "--hz", "fast"], 2, "invalid float value: 'fast'"),
    (["router", "--zenoh-mode", "client"], 2, "a router runs in router mode"),
    # a missing input file: named, no "[Errno 2]"
    (["replay", "info", "{tmp}/none.mcap"], 2, "none.mcap' does not exist"),
    (["replay", "play", "{tmp}/none.mcap"], 2, "none.mcap' does not exist"),
    (["replay", "export", "{tmp}/none.mcap", "--out", "{tmp}/c.cdr"], 2, "none.mcap' does not exist"),
    (["replay", "convert", "{tmp}/none.bag", "{tmp}/o.mcap"], 2, "none.bag' does not exist"),
    (
        ["query", "sofia/{robot}/detector/detect", "--payload", "{tmp}/none.cdr"],
        2,
        "none.cdr' does not exist",
    ),
    (["detect", "{tmp}/none.pcd"], 2, "none.pcd: no such file"),
    (["calibrate", "--poses", "{tmp}/none.txt", "--tfs", "{tmp}/none.txt"], 2, "none.txt"),
    # success
    (["schemas", "export", "{tmp}/schemas"], 0, ""),
]
# as separate processes, side by side: the job failed (nobody answers, nothing arrives), and the
# process exit code of a usage error and of a success
PROCESSES: list[tuple[list[str], int, str]] = [
    (["query", "sofia/{robot}/nobody/here", "--timeout", "1"], 1, "no reply from sofia/{robot}/nobody/here"),
    (["health", "detector", "--timeout", "1"], 1, "detector:"),
    (
        ["echo", "sofia/{robot}/nothing", "--count", "1", "--timeout", "1"],
        1,
        "sofia echo: 0 of 1 messages on sofia/{robot}/nothing within 1 s",
    ),
    (["replay", "play"], 2, "the following arguments are required: file"),
    (["--version"], 0, ""),
]


@pytest.mark.parametrize("argv,code,text", IN_PROCESS, ids=[" ".join(c[0][:2]) for c in IN_PROCESS])
def test_exit_code(
    argv: list[str], code: int, text: str, tmp_path: Path, robot_id: str, capsys: pytest.CaptureFixture[str],
    root_logging: None,
) -> None:  # fmt: skip
    args = [a.format(tmp=tmp_path, robot=robot_id) for a in argv]
    try:
        got = cli.main(args)
    except SystemExit as e:  # argparse's usage errors
        got = int(e.code or 0)
    err = capsys.readouterr().err
    assert got == code, err
    assert text in err and "Traceback" not in err and "[Errno" not in err, err
    if code == 0:
        assert list((tmp_path / "schemas").glob("*.schema.json"))  # the successful job did its work


def test_exit_code_of_processes(tmp_path: Path, robot_id: str) -> None:
    env = dict(os.environ, SOFIA_ROBOT=robot_id)
    procs = []
    for argv, code, text in PROCESSES:
        args = [a.format(tmp=tmp_path, robot=robot_id) for a in argv]
        p = subprocess.Popen(
            [SOFIA, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
        )
        procs.append((args, code, text.format(robot=robot_id), p))
    wrong = []
    for args, code, text, p in procs:
        out, err = p.communicate(timeout=300)  # generous: the machine is shared
        if p.returncode != code or text not in err or "Traceback" in err:
            wrong.append(
                f"sofia {' '.join(args)}: exit {p.returncode} (expected {code}), stderr:\n{err[-800:]}"
            )
    assert not wrong, "\n\n".join(wrong)
    assert procs[-1][3].returncode == 0 and out.startswith("sofia ")  # --version prints the version
