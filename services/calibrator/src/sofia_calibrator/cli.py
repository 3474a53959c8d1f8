"""``sofia calibrate`` (for people: files in, calibration out) and ``sofia calibrator`` (the service)."""

from __future__ import annotations

import argparse
import json
import logging
from importlib.metadata import entry_points

from sofia_runtime.output import add_json_option, float_arg
from sofia_runtime.zenoh_config import add_zenoh_args
from sofia_schemas.frames import CAMERA_FRAME as CHILD_FRAME
from sofia_schemas.frames import FLANGE_FRAME as PARENT_FRAME
from sofia_schemas.keys import add_robot_arg

from .cli_inputs import add_target_args, run_target
from .inbox import QUERY_DEADLINE_S
from .samples.errors import MAX_SAMPLES

log = logging.getLogger(__name__)

# modes under `sofia calibrate` that other packages add (the arm's `auto`): each entry point is a
# function called with the `calibrate` parser
CALIBRATE_MODES = "sofia.calibrate_modes"


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "calibrate", help="hand-eye calibration T_flange_cam from blob samples",
        description="Calibrate the flange-mounted camera (T_flange_cam: camera points into the flange "
        "frame, metres) from a blob seen from several flange poses. No initial guess is needed.",
    )  # fmt: skip
    src = p.add_argument_group("samples (one of)")
    src.add_argument("--poses", help="lab poses.txt: blob x,y,z per line, camera frame, metres")
    src.add_argument("--tfs", help="lab tfs.txt: flange poses (translation + rotation x y z w blocks)")
    src.add_argument("--joints", help="Panda joint positions, 7 per line (radians), paired with --poses")
    src.add_argument("--samples", help="CSV or JSON sample file")
    src.add_argument("--mcap", help="MCAP recording with blob observations and flange poses")
    src.add_argument(
        "--from-clouds", action="store_true", help="with --mcap: extract the blob from the clouds"
    )
    add_target_args(p)
    p.add_argument("--guess", nargs=7, type=float, metavar=("X", "Y", "Z", "QX", "QY", "QZ", "QW"),
                   help="optional initial T_flange_cam (never required); quaternion x y z w")  # fmt: skip
    p.add_argument("--loss", default="linear", choices=("linear", "huber", "cauchy"),
                   help="robust loss of the fit: linear = least squares (default linear)")  # fmt: skip
    p.add_argument(
        "--noise", default="auto", choices=("auto", "depth", "uniform"),
        help="noise model, its level estimated from the data: auto = isotropic + the D435's (default)",
    )  # fmt: skip
    p.add_argument(
        "--correction", default="auto", choices=("auto", "rigid", "depth_scale", "ray_scale"),
        help="camera correction fitted with the transform: auto = chosen by an F-test (default)",
    )  # fmt: skip
    p.add_argument("--scale-prior", metavar="RESULT.yaml",
                   help="an earlier calibration of the same camera: its depth scale is the prior of this "
                   "one's (helps small sets; default none)")  # fmt: skip
    add_frame_args(p)
    p.add_argument("--keep-outliers", action="store_true", help="report the fit with every sample")
    add_json_option(p, "the CalibrationResult, one object", text="YAML")
    p.add_argument("--yaml", metavar="OUT", help="also write the result as YAML")
    p.add_argument("--plot", metavar="OUT.png", help="write the dissipation plot")
    p.set_defaults(func=run_calibrate)
    for ep in sorted(entry_points(group=CALIBRATE_MODES), key=lambda e: e.name):
        try:
            ep.load()(p)
        except ImportError as e:  # a package whose optional dependencies are missing
            log.debug("calibrate mode %s unavailable: %s", ep.name, e)

    c = sub.add_parser("calibrator", help="the calibrator service")
    cs = c.add_subparsers(dest="calibrator_cmd", required=True, metavar="ACTION")
    s = cs.add_parser("serve", help="run the online calibrator service on Zenoh")
    s.add_argument("--state-dir", default="./var/calibrator", help="sample database and saved results")
    s.add_argument("--from-clouds", action="store_true", help="also extract the blob from camera clouds")
    s.add_argument("--cloud-target", choices=("blob", "ball"), default="blob",
                   help="with --from-clouds: the blob on the sheet, or a coloured ball (default blob)")  # fmt: skip
    s.add_argument(
        "--ball-radius", type=float, metavar="M", help="the ball's radius, metres (default: fitted)"
    )
    s.add_argument("--setup", choices=("eye-in-hand", "eye-to-hand"), default="eye-in-hand",
                   help="solve T_flange_cam (eye-in-hand) or T_base_cam (eye-to-hand: the target on the "
                   "flange); a solve query's options may change it (default eye-in-hand)")  # fmt: skip
    s.add_argument("--scale-prior", metavar="RESULT.yaml",
                   help="an earlier calibration of the same camera: its depth scale is the prior of each "
                   "solve's (default none)")  # fmt: skip
    s.add_argument("--tolerance-ms", type=float, default=50.0, help="pose/blob stamp gap, ms")
    s.add_argument("--min-samples", type=int, default=3, help="samples before the first solve")
    s.add_argument("--max-samples", type=int, default=MAX_SAMPLES,
                   help=f"samples kept at most; more are refused (default {MAX_SAMPLES})")  # fmt: skip
    s.add_argument("--query-deadline", type=_seconds, default=QUERY_DEADLINE_S, metavar="S",
                   help="a query the worker reaches more than S seconds after it arrived is answered "
                   f"'busy, retry' (default {QUERY_DEADLINE_S:g}; clients wait 10 s)")  # fmt: skip
    add_robot_arg(s)
    add_frame_args(s)
    add_zenoh_args(s)
    s.set_defaults(func=run_service)


_seconds = float_arg("a positive number of seconds", lambda s: 0.0 < s < float("inf"))


def add_frame_args(p: argparse.ArgumentParser) -> None:
    """--parent-frame / --child-frame, defaulting to the lab's launch file."""
    p.add_argument("--parent-frame", default=PARENT_FRAME, help=f"flange frame (default {PARENT_FRAME})")
    p.add_argument("--child-frame", default=CHILD_FRAME, help=f"camera frame (default {CHILD_FRAME})")


def run_calibrate(args: argparse.Namespace) -> int:
    """Print and write the calibration's result (YAML or JSON, --yaml, --plot); 0 when it passes."""
    from .formats import to_message, to_yaml

    cal = run_target(args)
    msg = to_message(cal)
    if args.yaml:
        with open(args.yaml, "w") as f:
            f.write(to_yaml(msg))
    if args.plot:
        from .plot import plot_calibration

        plot_calibration(cal, args.plot)
    if args.json:
        print(json.dumps(msg.model_dump(mode="json")))
    else:
        print(to_yaml(msg), end="")
    return 0 if cal.passes else 1


def run_service(args: argparse.Namespace) -> int:
    from .service import main

    return main(args)
