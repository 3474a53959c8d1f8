"""``sofia demo``: the main job on a fresh machine.

Makes the synthetic recordings if missing, starts the system (router, detector, calibrator,
emulated gripper) as local processes, replays a board recording and prints each detection live
against the ground truth, sends a detect query, replays a calibration session and prints the
calibrated transform against the truth, runs open/grasp/release on the emulated gripper, writes
the detection and dissipation plots, and ends with a summary.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import zenoh
from sofia_runtime import zenoh_config
from sofia_runtime.limits import ClipFilter
from sofia_runtime.output import add_command, emit
from sofia_schemas import Keys
from sofia_schemas.board import BOARD_HELP
from sofia_schemas.keys import default_robot

from .bus import wait_until
from .launcher import Launcher, ServiceSpec, all_ready, board_args
from .summary import Summary, say

log = logging.getLogger("sofia.demo")


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = add_command(
        sub, "demo", _main, "the end-to-end demo on synthetic recordings (no hardware)",
        "the summary of every step, one object; the running commentary goes to stderr",
        description="Make synthetic recordings if missing, start the services, replay board scenes and a "
        "calibration session, check every result against the recordings' ground truth, drive the "
        "emulated gripper and write plots. Exit 0 only when every step passes, 1 otherwise.",
    )  # fmt: skip
    p.add_argument("--out", type=Path, default=Path("var/demo"),
                   help="folder of the plots, logs and service state (default var/demo)")  # fmt: skip
    p.add_argument("--recordings", type=Path, default=Path("var/recordings"),
                   help="folder of the synthetic recordings, made when missing (default var/recordings)")  # fmt: skip
    p.add_argument("--n-scenes", type=int, default=12, metavar="N",
                   help="board scenes in a new scenes recording (default 12)")  # fmt: skip
    p.add_argument("--scenes", type=int, dest="n_scenes", help=argparse.SUPPRESS)  # old name of --n-scenes
    p.add_argument("--n-poses", type=int, default=12, metavar="N",
                   help="robot poses of a new calibration recording (default 12)")  # fmt: skip
    p.add_argument("--poses", type=int, dest="n_poses", help=argparse.SUPPRESS)  # old name of --n-poses
    p.add_argument("--board", type=Path, default=None, help=BOARD_HELP)
    p.add_argument("--robot", default=None, help="robot id of every key (default $SOFIA_ROBOT or panda)")
    p.add_argument("--no-cell", action="store_true",
                   help="skip the closed loop in the simulated cell (franky-sim: calibrate, detect, pick and place)")  # fmt: skip


def _main(args: argparse.Namespace) -> int:
    summary = Summary()
    t0 = time.monotonic()
    with contextlib.redirect_stdout(sys.stderr) if args.json else contextlib.nullcontext():
        code = run_demo(args.out, args.recordings, args.n_scenes, args.n_poses, args.board, args.robot,
                        not args.no_cell, summary)  # fmt: skip
    result = {"ok": code == 0, "seconds": round(time.monotonic() - t0, 1), "steps": summary.as_list()}
    if args.json:
        emit(args, result, "")
    return code


@contextlib.contextmanager
def launcher_log(path: Path) -> Iterator[None]:
    """The launcher's info lines (service started, stopped) go to ``path``, not to the terminal;
    its warnings (a service died, restarts) go to both."""
    logger = logging.getLogger("sofia.up")
    path.parent.mkdir(parents=True, exist_ok=True)
    fmt = logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s")
    handlers: list[logging.Handler] = [logging.FileHandler(path), logging.StreamHandler()]
    handlers[1].setLevel(logging.WARNING)
    for h in handlers:
        h.setFormatter(fmt)
        h.addFilter(ClipFilter())
        logger.addHandler(h)
    propagate, logger.propagate = logger.propagate, False
    try:
        yield
    finally:
        logger.propagate = propagate
        for h in handlers:
            logger.removeHandler(h)
            h.close()


def make_recordings(recordings: Path, n_scenes: int, n_poses: int) -> tuple[Path, Path]:
    from sofia_replay.synth import write_calibration_session, write_scene_set

    recordings.mkdir(parents=True, exist_ok=True)
    scenes, calib = recordings / "scenes.mcap", recordings / "calibration.mcap"
    if not scenes.exists():
        say(f"making {scenes} ({n_scenes} synthetic board scenes, D435-like noise) ...")
        write_scene_set(scenes.with_suffix(".tmp"), "mixed", n_scenes, seed=1, rate_hz=5.0)
        scenes.with_suffix(".tmp").rename(scenes)
    if not calib.exists():
        say(f"making {calib} ({n_poses}-pose calibration session) ...")
        write_calibration_session(calib.with_suffix(".tmp"), n_poses, seed=2)
        calib.with_suffix(".tmp").rename(calib)
    return scenes, calib


def run_demo(out: Path, recordings: Path, n_scenes: int = 12, n_poses: int = 12, board: Path | None = None,
             robot: str | None = None, cell: bool = True, summary: Summary | None = None) -> int:  # fmt: skip
    """Every step of the demo; the launcher's log lines go to ``out/logs/launcher.log``."""
    out.mkdir(parents=True, exist_ok=True)
    with launcher_log(out / "logs" / "launcher.log"):
        return _run(
            out, recordings, n_scenes, n_poses, board, robot or default_robot(), cell, summary or Summary()
        )


def _run(out: Path, recordings: Path, n_scenes: int, n_poses: int, board: Path | None, robot: str, cell: bool,
         summary: Summary) -> int:  # fmt: skip
    from . import steps  # the steps' checks need SciPy's rotations: loaded when the demo runs

    keys = Keys(robot)
    t0 = time.monotonic()
    scenes_mcap, calib_mcap = make_recordings(recordings, n_scenes, n_poses)
    specs = [
        ServiceSpec("detector", ["detector", "serve", *board_args(board)], "detector"),
        ServiceSpec(
            "calibrator", ["calibrator", "serve", "--state-dir", str(out / "calibrator")], "calibrator"
        ),
        ServiceSpec(
            "gripper",
            ["gripper", "serve", "--emulate", "--object-width", str(steps.OBJECT_WIDTH_MM)],
            "gripper",
        ),
    ]
    launcher = Launcher(specs, out / "logs", robot)
    say(f"starting services (logs in {out / 'logs'}) ...")
    launcher.start()
    try:
        with zenoh.open(zenoh_config()) as session:

            def all_healthy() -> bool:
                launcher.poll()
                return all_ready(launcher.check_health(session))

            healthy = wait_until(all_healthy, 90)
            say(launcher.table())
            summary.add(
                "services up",
                "detector, calibrator, gripper healthy" if healthy else "not all healthy",
                healthy,
            )
            if not healthy:
                return _finish(summary, t0)
            steps.detections(session, keys, scenes_mcap, robot, summary)
            if steps.calibration(session, keys, calib_mcap, robot, summary):
                steps.camera_frame(session, keys, scenes_mcap, robot, summary)
            steps.gripper(session, keys, summary)
        steps.plots(scenes_mcap, calib_mcap, out, robot, summary)
    finally:
        launcher.stop()
    if cell:  # the closed loop: the arm calibrates, the detector sees through it, the arm picks and places
        from .closed_loop import run_cell

        run_cell(out, robot, board, summary)
    return _finish(summary, t0)


def _finish(summary: Summary, t0: float) -> int:
    say(summary.table())
    say(f"demo took {time.monotonic() - t0:.0f} s")
    return 0 if summary.ok else 1


if __name__ == "__main__":
    sys.exit(run_demo(Path("var/demo"), Path("var/recordings")))
