"""``sofia replay {play,info,convert,export}`` and ``sofia synth {scenes,calibration}``.

Exit codes: 0 done, 1 the job failed, 2 a usage or input error (a missing or unreadable file, a
topic the recording does not have).
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from pathlib import Path

from sofia_runtime.output import add_command, add_group, emit
from sofia_runtime.zenoh_config import ZenohOptions, add_zenoh_args, open_session
from sofia_schemas.keys import default_robot

log = logging.getLogger("sofia.replay")


def register_replay(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    s = add_group(sub, "replay", "play, inspect, convert and export recordings (MCAP, ROS 1 bags)",
                  description="Stream MCAP recordings onto the bus, summarise them, convert the lab's ROS 1 "
                  "bags and export single messages (e.g. a cloud for `sofia query --payload`).")  # fmt: skip

    play = add_command(s, "play", _play, "stream an MCAP recording to its Zenoh keys")
    play.add_argument("file", type=Path, help="MCAP file")
    speed = play.add_mutually_exclusive_group()
    speed.add_argument("--rate", type=float, default=1.0, metavar="X",
                       help="playback speed, a multiplier of the recorded rate (default 1.0: real time)")  # fmt: skip
    speed.add_argument("--fast", action="store_true", help="as fast as possible, no timing (default: off)")
    play.add_argument(
        "--loop", action="store_true", help="start again at the end, until stopped (default: off)"
    )
    play.add_argument(
        "--restamp", action=argparse.BooleanOptionalAction, default=None,
        help="rewrite header stamps to the publish time, wall clock (default: on with --loop, so stamps "
        "never jump back; off otherwise: the recorded stamps)",
    )  # fmt: skip
    play.add_argument("--map", action="append", default=[], metavar="TOPIC=KEY",
                      help="publish TOPIC on Zenoh KEY, repeatable (default: the SofIA key of each topic)")  # fmt: skip
    play.add_argument("--topic", action="append", default=None, metavar="TOPIC",
                      help="play only TOPIC, repeatable (default: every topic)")  # fmt: skip
    play.add_argument("--start", type=float, default=None, metavar="S",
                      help="start S seconds after the first message (default: the beginning)")  # fmt: skip
    play.add_argument("--end", type=float, default=None, metavar="S",
                      help="stop S seconds after the first message (default: the end)")  # fmt: skip
    play.add_argument("--robot", default=None, help="robot id of the keys (default $SOFIA_ROBOT or panda)")
    play.add_argument(
        "--congestion", choices=["block", "drop"], default="block",
        help="block: lossless, a stalled subscriber slows the replay; drop: live-sensor behaviour "
        "(default block)",
    )  # fmt: skip
    play.add_argument(
        "--wait-subscribers", type=float, default=0.0, metavar="S",
        help="wait up to S seconds until every key has a subscriber before playing (default 0: no wait)",
    )  # fmt: skip
    play.add_argument("--progress", type=float, default=5.0, metavar="S",
                      help="seconds between progress log lines (default 5)")  # fmt: skip
    play.add_argument(
        "--preload", action="store_true",
        help="read the played messages into memory once, decompressed, before playing: no file reading "
        "or decompression while playing (needs their size in RAM, logged; default: off, read lazily)",
    )  # fmt: skip
    add_zenoh_args(play)

    info = add_command(
        s, "info", _info, "topics, counts, schemas and duration of an MCAP file", "the summary, one object"
    )
    info.add_argument("file", type=Path, help="MCAP file")
    info.add_argument(
        "--truth", action="store_true", help="also print the ground truth metadata (default: off)"
    )

    conv = add_command(s, "convert", _convert, "convert a ROS 1 bag (e.g. perception.bag) to MCAP",
                       "the counts per topic, one object")  # fmt: skip
    conv.add_argument("input", type=Path, help="ROS 1 .bag")
    conv.add_argument("output", type=Path, help="MCAP file to write (not written when nothing converts)")
    conv.add_argument("--rename", action="append", default=[], metavar="IN=OUT",
                      help="write topic IN as OUT, repeatable (default: names kept)")  # fmt: skip
    conv.add_argument(
        "--topic", action="append", dest="rename", help=argparse.SUPPRESS
    )  # old name of --rename
    conv.add_argument("--only", action="append", default=None, metavar="TOPIC",
                      help="convert only TOPIC, repeatable (default: every topic of a converted type)")  # fmt: skip
    conv.add_argument("--compression", choices=["zstd", "lz4", "none"], default="zstd",
                      help="chunk compression of the MCAP (default zstd)")  # fmt: skip

    exp = add_command(
        s, "export", _export, "write one recorded message's payload (CDR bytes) to a file",
        "the message exported, one object",
        description="Write the payload of one message exactly as recorded, e.g. a cloud to send with "
        "`sofia query sofia/panda/detector/detect --payload cloud.cdr`.",
    )  # fmt: skip
    exp.add_argument("file", type=Path, help="MCAP file")
    exp.add_argument("--topic", default=None,
                     help="topic to export from (default: /pc_glob, else the camera-frame clouds)")  # fmt: skip
    exp.add_argument("--index", type=int, default=0, metavar="N",
                     help="which message of the topic, 0 = first, -1 = last (default 0)")  # fmt: skip
    exp.add_argument("--out", type=Path, required=True, metavar="FILE", help="file to write (e.g. cloud.cdr)")


def _play(args: argparse.Namespace) -> int:
    from sofia_runtime.service import StopFlag

    from .convert import parse_topic_map
    from .player import Player, PlayOptions

    options = PlayOptions(
        rate=args.rate, fast=args.fast, loop=args.loop, start_s=args.start, end_s=args.end,
        topic_map=parse_topic_map(args.map), topics=args.topic, congestion=args.congestion,
        wait_subscribers_s=args.wait_subscribers, progress_period_s=args.progress,
        restamp=args.loop if args.restamp is None else args.restamp, preload=args.preload,
    )  # fmt: skip
    robot = args.robot or default_robot()
    stop = StopFlag()
    with open_session(ZenohOptions.from_args(args)) as session:
        player = Player(session, args.file, robot, options)
        try:
            player.run(stop)
        finally:
            player.close()
    return 0


def _info(args: argparse.Namespace) -> int:
    from .mcap_io import read_truth, summary

    s = summary(args.file)
    truth = read_truth(args.file) if args.truth else None
    if args.json:
        out = s.to_dict()
        if args.truth:
            out["truth"] = truth
        emit(args, out, "")
    else:
        print(s.format())
        if args.truth:
            print("truth:", json.dumps(truth, indent=2))
    return 0


def _convert(args: argparse.Namespace) -> int:
    from .convert import convert_bag, parse_topic_map

    report = convert_bag(args.input, args.output, parse_topic_map(args.rename), args.only, args.compression)
    lines = [f"{args.output}: {report.n_written} messages"]
    lines += [f"  {topic}: {n}" for topic, n in sorted(report.written.items())]
    lines += [f"  skipped {topic} ({msgtype})" for topic, msgtype in sorted(report.skipped_topics.items())]
    lines += [f"  rejected {n} messages of {topic}" for topic, n in sorted(report.rejected.items())]
    result = {"output": args.output, "messages": report.n_written, "written": report.written,
              "skipped": report.skipped_topics, "rejected": report.rejected}  # fmt: skip
    emit(args, result, "\n".join(lines))
    return 0


def _export(args: argparse.Namespace) -> int:
    from .export import export_message

    m = export_message(args.file, args.out, args.topic, args.index)
    result = {"out": args.out, "topic": m.topic, "index": args.index, "schema": m.schema_name,
              "bytes": len(m.data), "log_time_ns": m.log_time_ns}  # fmt: skip
    text = f"{args.out}: {m.topic}[{args.index}] ({m.schema_name}, {len(m.data)} bytes, log time {m.log_time_ns} ns)"
    emit(args, result, text)
    return 0


# --- synthetic data ---------------------------------------------------------------------------------
def register_synth(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    s = add_group(sub, "synth", "render synthetic SofIA recordings (needs open3d)", metavar="KIND",
                  description="Render synthetic MCAP recordings with D435-like noise and their ground truth.")  # fmt: skip

    sc = add_command(s, "scenes", _synth_scenes, "board scenes with objects, clouds in base and camera frame",
                     "the file written, one object")  # fmt: skip
    sc.add_argument("output", type=Path, help="MCAP file to write")
    sc.add_argument("--kind", default="mixed", choices=["one", "empty", "nonred", "two", "mixed"],
                    help="objects per scene: one on a red field, empty board, one on a non-red field, "
                    "two, or a mix (default mixed)")  # fmt: skip
    sc.add_argument("-n", "--n-scenes", dest="n", type=int, default=10, metavar="N",
                    help="number of scenes, one cloud each (default 10)")  # fmt: skip
    sc.add_argument("--seed", type=int, default=0, help="random seed of the scenes and noise (default 0)")
    sc.add_argument("--hz", type=float, default=10.0, help="frame rate of the recording, Hz (default 10)")
    sc.add_argument("--rate", type=float, dest="hz", help=argparse.SUPPRESS)  # old name of --hz
    sc.add_argument("--board", type=Path, default=None, help="board YAML/JSON (default: the shipped board)")
    sc.add_argument("--frames", choices=["base", "camera", "both"], default="both",
                    help="clouds in the base frame (/pc_glob), camera frame, or both (default both)")  # fmt: skip

    cal = add_command(s, "calibration", _synth_calibration, "a hand-eye calibration session (blob target)",
                      "the file written, one object")  # fmt: skip
    cal.add_argument("output", type=Path, help="MCAP file to write")
    cal.add_argument("--n-poses", type=int, default=12, metavar="N",
                     help="number of robot poses of the session (default 12)")  # fmt: skip
    cal.add_argument("--poses", type=int, dest="n_poses", help=argparse.SUPPRESS)  # old name of --n-poses
    cal.add_argument("--seed", type=int, default=0, help="random seed of the poses and noise (default 0)")
    cal.add_argument("--no-clouds", action="store_true",
                     help="only poses and blob observations, no camera clouds (default: with clouds)")  # fmt: skip


def _synth_scenes(args: argparse.Namespace) -> int:
    from sofia_schemas import Board

    from .synth.record import write_scene_set

    board = Board.from_file(args.board) if args.board else None
    args.output.parent.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    log.info("rendering %d scenes (%s) into %s ...", args.n, args.kind, args.output)
    write_scene_set(
        args.output,
        kind=args.kind,
        n=args.n,
        seed=args.seed,
        rate_hz=args.hz,
        board=board,
        frames=args.frames,
    )
    seconds = time.monotonic() - t0
    log.info("%d scenes written in %.1f s", args.n, seconds)
    emit(args, {"output": args.output, "scenes": args.n, "seconds": round(seconds, 1)}, str(args.output))
    return 0


def _synth_calibration(args: argparse.Namespace) -> int:
    from .synth.record import write_calibration_session

    args.output.parent.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    log.info("rendering a %d-pose calibration session into %s ...", args.n_poses, args.output)
    write_calibration_session(args.output, n_poses=args.n_poses, seed=args.seed, clouds=not args.no_clouds)
    seconds = time.monotonic() - t0
    log.info("%d poses written in %.1f s", args.n_poses, seconds)
    emit(args, {"output": args.output, "poses": args.n_poses, "seconds": round(seconds, 1)}, str(args.output))
    return 0
