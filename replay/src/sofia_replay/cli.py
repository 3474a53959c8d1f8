"""``sofia replay {play,info,convert}`` and ``sofia synth {scenes,calibration}``."""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

from sofia_schemas.keys import default_robot
from sofia_schemas.zenoh_config import ZenohOptions, add_zenoh_args, open_session

log = logging.getLogger("sofia.replay")


def register_replay(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("replay", help="play, inspect and convert recordings (MCAP, ROS 1 bags)")
    s = p.add_subparsers(dest="replay_cmd", required=True)

    play = s.add_parser("play", help="stream an MCAP recording to its Zenoh keys")
    play.add_argument("file", type=Path, help="MCAP file")
    speed = play.add_mutually_exclusive_group()
    speed.add_argument("--rate", type=float, default=1.0, help="speed multiplier of the recorded rate")
    speed.add_argument("--fast", action="store_true", help="as fast as possible (no timing)")
    play.add_argument("--loop", action="store_true", help="start again at the end, until stopped")
    play.add_argument(
        "--restamp", action="store_true",
        help="rewrite header stamps to the publish time (live-like data; loops get fresh stamps)",
    )  # fmt: skip
    play.add_argument(
        "--map", action="append", default=[], metavar="TOPIC=KEY", help="publish TOPIC on Zenoh KEY"
    )
    play.add_argument("--topic", action="append", default=None, metavar="TOPIC", help="play only TOPIC")
    play.add_argument(
        "--start", type=float, default=None, metavar="S", help="from S s after the first message"
    )
    play.add_argument(
        "--end", type=float, default=None, metavar="S", help="until S s after the first message"
    )
    play.add_argument("--robot", default=None, help="robot id of the keys (default $SOFIA_ROBOT or panda)")
    play.add_argument(
        "--congestion", choices=["block", "drop"], default="block",
        help="block: lossless, a stalled subscriber slows the replay; drop: live-sensor behaviour",
    )  # fmt: skip
    play.add_argument(
        "--wait-subscribers", type=float, default=0.0, metavar="S",
        help="wait up to S s until every key has a subscriber before playing",
    )  # fmt: skip
    play.add_argument("--progress", type=float, default=5.0, metavar="S", help="progress log period")
    add_zenoh_args(play)
    play.set_defaults(func=_play)

    info = s.add_parser("info", help="topics, counts, schemas and duration of an MCAP file")
    info.add_argument("file", type=Path)
    info.add_argument("--json", action="store_true", help="print JSON")
    info.add_argument("--truth", action="store_true", help="also print the ground truth metadata")
    info.set_defaults(func=_info)

    conv = s.add_parser("convert", help="convert a ROS 1 bag (e.g. perception.bag) to MCAP")
    conv.add_argument("input", type=Path, help="ROS 1 .bag")
    conv.add_argument("output", type=Path, help="MCAP file to write")
    conv.add_argument("--topic", action="append", default=[], metavar="IN=OUT", help="rename topic IN to OUT")
    conv.add_argument("--only", action="append", default=None, metavar="TOPIC", help="convert only TOPIC")
    conv.add_argument("--compression", choices=["zstd", "lz4", "none"], default="zstd")
    conv.set_defaults(func=_convert)


def _play(args: argparse.Namespace) -> int:
    from sofia_schemas.service import StopFlag

    from .convert import parse_topic_map
    from .player import Player, PlayOptions

    options = PlayOptions(
        rate=args.rate,
        fast=args.fast,
        loop=args.loop,
        start_s=args.start,
        end_s=args.end,
        topic_map=parse_topic_map(args.map),
        topics=args.topic,
        congestion=args.congestion,
        wait_subscribers_s=args.wait_subscribers,
        progress_period_s=args.progress,
        restamp=args.restamp,
    )
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
        print(json.dumps(out, indent=2))
    else:
        print(s.format())
        if args.truth:
            print("truth:", json.dumps(truth, indent=2))
    return 0


def _convert(args: argparse.Namespace) -> int:
    from .convert import convert_bag, parse_topic_map

    report = convert_bag(args.input, args.output, parse_topic_map(args.topic), args.only, args.compression)
    print(f"{args.output}: {report.n_written} messages")
    for topic, n in sorted(report.written.items()):
        print(f"  {topic}: {n}")
    for topic, msgtype in sorted(report.skipped_topics.items()):
        print(f"  skipped {topic} ({msgtype})")
    for topic, n in sorted(report.rejected.items()):
        print(f"  rejected {n} messages of {topic}")
    return 0 if report.n_written else 1


# --- synthetic data ---------------------------------------------------------------------------------
def register_synth(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser("synth", help="render synthetic SofIA recordings (needs open3d)")
    s = p.add_subparsers(dest="synth_cmd", required=True)

    sc = s.add_parser("scenes", help="board scenes with objects, clouds in base and camera frame")
    sc.add_argument("output", type=Path, help="MCAP file to write")
    sc.add_argument("--kind", default="mixed", choices=["one", "empty", "nonred", "two", "mixed"])
    sc.add_argument("-n", type=int, default=10, help="number of frames")
    sc.add_argument("--seed", type=int, default=0)
    sc.add_argument("--rate", type=float, default=10.0, help="frame rate of the recording, Hz")
    sc.add_argument("--board", type=Path, default=None, help="board YAML/JSON (default: the shipped board)")
    sc.add_argument("--frames", choices=["base", "camera", "both"], default="both")
    sc.set_defaults(func=_synth_scenes)

    cal = s.add_parser("calibration", help="a hand-eye calibration session (blob target)")
    cal.add_argument("output", type=Path, help="MCAP file to write")
    cal.add_argument("--poses", type=int, default=12)
    cal.add_argument("--seed", type=int, default=0)
    cal.add_argument("--no-clouds", action="store_true", help="only poses and blob observations")
    cal.set_defaults(func=_synth_calibration)


def _synth_scenes(args: argparse.Namespace) -> int:
    from sofia_schemas import Board

    from .synth.record import write_scene_set

    board = Board.from_file(args.board) if args.board else None
    args.output.parent.mkdir(parents=True, exist_ok=True)
    write_scene_set(
        args.output,
        kind=args.kind,
        n=args.n,
        seed=args.seed,
        rate_hz=args.rate,
        board=board,
        frames=args.frames,
    )
    print(args.output)
    return 0


def _synth_calibration(args: argparse.Namespace) -> int:
    from .synth.record import write_calibration_session

    args.output.parent.mkdir(parents=True, exist_ok=True)
    write_calibration_session(args.output, n_poses=args.poses, seed=args.seed, clouds=not args.no_clouds)
    print(args.output)
    return 0
