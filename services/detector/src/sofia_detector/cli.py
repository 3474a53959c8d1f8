"""``sofia detect FILE...`` (for people) and ``sofia detector serve`` (the service)."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

from sofia_runtime.output import add_command, add_group, float_arg
from sofia_runtime.zenoh_config import ZenohOptions, add_zenoh_args
from sofia_schemas import Board
from sofia_schemas.board import BOARD_HELP
from sofia_schemas.keys import add_robot_arg, default_robot
from sofia_schemas.messages import Detection
from sofia_schemas.messages.calibration import read_calibration_file

from .detect import detect
from .errors import DetectorError, WrongCloud
from .pick import PickParams
from .readers import FileCloud, iter_file_clouds
from .sanity import diagnose
from .service_config import ServiceConfig

log = logging.getLogger("sofia.detect")


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    d = add_command(sub, "detect", _detect_all, "detect the objects on the board in cloud files",
                    json="one object per cloud and line")  # fmt: skip
    d.add_argument("files", nargs="+", type=Path, metavar="FILE", help=".mcap, .pcd, .ply or .npy")
    d.add_argument("--board", type=Path, help=BOARD_HELP)
    d.add_argument(
        "--plot", type=Path, metavar="OUT.png",
        help="draw the board from above into OUT.png; several clouds: OUT-01.png, OUT-02.png, ... (one per cloud)",
    )  # fmt: skip
    d.add_argument(
        "--transform", type=Path, metavar="FILE",
        help="T_flange_cam YAML/JSON: also detect in the camera-frame clouds of .mcap files",
    )  # fmt: skip
    serve = add_command(add_group(sub, "detector", "the detector service"), "serve", _serve,
                        "run the detector service on Zenoh")  # fmt: skip
    serve.add_argument("--board", type=Path, help=BOARD_HELP)
    serve.add_argument(
        "--transform", type=Path, metavar="FILE", help="T_flange_cam YAML/JSON (else the calibrator's)"
    )
    add_robot_arg(serve)
    serve.add_argument(
        "--backlog", type=int, default=ServiceConfig.backlog, metavar="N",
        help="clouds kept while busy (default 1: only the latest, older ones are dropped and counted; "
        "N > 1: a stall of up to N-1 frames loses nothing, at most N-1 frames late)",
    )  # fmt: skip
    serve.add_argument(
        "--pose-wait", type=float, default=ServiceConfig.pose_wait_s, metavar="S",
        help="seconds a camera-frame cloud waits for the flange pose of its stamp, queries being "
        "served meanwhile (default %(default)s)",
    )  # fmt: skip
    serve.add_argument(
        "--pick-min-confidence", type=_confidence, default=PickParams.min_confidence, metavar="C",
        help="publish pick targets only for objects of at least this confidence (default 0.5: not "
        "for truncated objects, whose centre is that of their visible part)",
    )  # fmt: skip
    add_zenoh_args(serve)


_confidence = float_arg("a confidence between 0 and 1", lambda c: 0.0 <= c <= 1.0)


def _serve(args: argparse.Namespace) -> int:
    from .service import main

    config = ServiceConfig(
        board=Board.load(args.board), robot=args.robot or default_robot(), zenoh=ZenohOptions.from_args(args),
        transform_file=args.transform, backlog=args.backlog, pose_wait_s=args.pose_wait,
        pick=PickParams(min_confidence=args.pick_min_confidence),
    )  # fmt: skip
    return main(config)


def _summary(fc: FileCloud, det: Detection) -> str:
    head = f"{fc.source}[{fc.index}] {det.status}: {len(det.objects)} object(s) in {det.timings_ms.get('total_ms', 0):.1f} ms"
    if det.detail:
        head += f" ({det.detail})"
    lines = [head]
    for obj in det.objects:
        c, m, e = obj.center, obj.centroid, obj.extents
        lines.append(
            f"  field {obj.field} {'allowed' if obj.allowed else 'NOT allowed'}: "
            f"centre ({c[0]:.4f}, {c[1]:.4f}, {c[2]:.4f}) m, centroid ({m[0]:.4f}, {m[1]:.4f}, {m[2]:.4f}) m, "
            f"extents {e[0] * 1e3:.0f} x {e[1] * 1e3:.0f} x {e[2] * 1e3:.0f} mm, "
            f"yaw {obj.yaw * 57.29578:.1f} deg, {obj.n_points} points, confidence {obj.confidence:.2f}"
            + (f", {obj.colour}" if obj.colour else "")
            + (f", {obj.visibility:.0%} in view ({', '.join(obj.truncated)})" if obj.truncated else "")
        )
    return "\n".join(lines)


# the Detection's fields in a line of --json, beside "file", "index" and "board"
RECORD = {"stamp_ns", "status", "objects", "board_normal", "board_center", "timings_ms", "transform", "source",
          "detail"}  # fmt: skip


def _numbered(out: Path, n: int) -> Path:
    """``OUT-01.png``, ``OUT-02.png``, ... for cloud ``n`` (from 0), numbered from 1 like the scenes."""
    return out.with_name(f"{out.stem}-{n + 1:02d}{out.suffix or '.png'}")


def _detect_all(args: argparse.Namespace) -> int:
    board = Board.load(args.board)
    T_flange_cam = read_calibration_file(args.transform)[0] if args.transform else None
    transform_name = f"file {args.transform}" if args.transform else None
    failures, n_clouds = 0, 0
    single = len(args.files) == 1 and args.files[0].suffix.lower() != ".mcap"
    for path in args.files:
        try:
            for fc in iter_file_clouds(path, board.frame_id, T_flange_cam, transform_name):
                det = detect(fc.points, board, stamp_ns=fc.stamp_ns, source=fc.source, rgb=fc.rgb)
                if det.status == "no_board" and (why := diagnose(fc.points, board)) is not None:
                    raise WrongCloud(fc.source, why)
                if fc.transform:
                    det = det.model_copy(update={"transform": fc.transform})
                rec = {"file": str(path), "index": fc.index, **det.model_dump(mode="json", include=RECORD)}
                print(
                    json.dumps(rec | {"board": board.digest}) if args.json else _summary(fc, det), flush=True
                )
                if args.plot:
                    from .plot import plot_detection

                    out = args.plot if single else _numbered(args.plot, n_clouds)
                    plot_detection(
                        fc.points, board, det, out, title=f"{out.stem}: {path.name}, cloud {fc.index + 1}"
                    )
                    log.info("plot written to %s", out)
                n_clouds += 1
        except DetectorError as e:
            failures += 1
            print(f"sofia detect: error: {e}", file=sys.stderr)
    if n_clouds == 0 and not failures:
        print(
            "sofia detect: no base-frame clouds found (camera-frame clouds need --transform)", file=sys.stderr
        )
        return 1
    return 2 if failures else 0  # a file that cannot be read or is not a board cloud: an input error
