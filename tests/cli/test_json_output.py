"""One output convention for every `sofia` command that prints results: text for people by
default, `--json` for machines (one JSON object, or one per line for a stream), offered through the
one shared option (`sofia_runtime.output`). The commands without it are the ones that run until
stopped or talk with a person, listed here with the reason."""

from __future__ import annotations

import argparse
import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from sofia_runtime import cli
from sofia_runtime.output import JSON_HELP, fields_text, jsonable

LAB = Path(__file__).parents[2] / "data" / "lab"

NO_RESULT = {  # command -> why it prints no result to format
    ("arm", "serve"): "a service, runs until stopped",
    ("calibrator", "serve"): "a service, runs until stopped",
    ("camera", "serve"): "a service, runs until stopped",
    ("detector", "serve"): "a service, runs until stopped",
    ("gripper", "serve"): "a service, runs until stopped",
    ("ros2", "serve"): "a service, runs until stopped",
    ("viz", "serve"): "a service, runs until stopped",
    ("router",): "a Zenoh router, runs until stopped",
    ("replay", "play"): "publishes on the bus; progress goes to the log",
    ("gripper", "emulate"): "prints its tty and answers fault commands typed on stdin",
    ("gripper", "calibrate"): "asks a person to type what the scale reads; writes the config file",
}


def commands(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()) -> Iterator[tuple[tuple[str, ...], argparse.ArgumentParser]]:  # fmt: skip
    """Every runnable command (a parser that sets ``func``) of the whole tree."""
    if parser.get_default("func") is not None:
        yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, child in action.choices.items():
                yield from commands(child, (*path, name))


def json_option(parser: argparse.ArgumentParser) -> argparse.Action | None:
    return next((a for a in parser._actions if "--json" in a.option_strings), None)


def test_every_command_that_prints_results_offers_the_shared_json_option() -> None:
    tree = dict(commands(cli.build_parser()))
    assert len(tree) > 30 and set(NO_RESULT) <= set(tree), set(NO_RESULT) - set(tree)
    missing = [
        f"sofia {' '.join(path)}"
        for path, p in tree.items()
        if path not in NO_RESULT
        and ((a := json_option(p)) is None or not (a.help or "").startswith(JSON_HELP))
    ]
    assert not missing, "no shared --json option: " + ", ".join(missing)
    pretending = [f"sofia {' '.join(path)}" for path in NO_RESULT if json_option(tree[path]) is not None]
    assert not pretending, "--json on a command that prints no result: " + ", ".join(pretending)


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small synthetic calibration session (poses and blob observations, no clouds)."""
    path = tmp_path_factory.mktemp("json") / "calibration.mcap"
    from sofia_replay.synth import write_calibration_session

    write_calibration_session(path, 3, seed=1, clouds=False)
    return path


# argv ({tmp}, {rec}, {lab}, {robot} filled in), exit code, JSON objects printed (None: one or more)
RUNS: list[tuple[list[str], int, int | None]] = [
    (["schemas", "export", "{tmp}/schemas"], 0, 1),
    (["ros2", "types"], 0, None),
    (["viz", "layout"], 0, 1),
    (["camera", "sim-truth", "--sim-scene", "board"], 0, 1),
    (["synth", "calibration", "{tmp}/c.mcap", "--n-poses", "2", "--no-clouds"], 0, 1),
    (["replay", "info", "{rec}"], 0, 1),
    (["replay", "export", "{rec}", "--topic", "/sofia/flange_pose", "--index", "-1", "--out", "{tmp}/p.cdr"], 0, 1),
    (["calibrate", "--poses", "{lab}/poses.txt", "--tfs", "{lab}/tfs.txt"], 0, 1),
    (["health", "nobody", "--robot", "{robot}", "--timeout", "1"], 1, 1),  # no reply: still one object
]  # fmt: skip


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = cli.main(argv)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("argv,code,n_objects", RUNS, ids=[" ".join(r[0][:2]) for r in RUNS])
def test_text_by_default_json_with_the_option(
    argv: list[str], code: int, n_objects: int | None, recording: Path, tmp_path: Path, robot_id: str,
    capsys: pytest.CaptureFixture[str], root_logging: None,
) -> None:  # fmt: skip
    args = [a.format(tmp=tmp_path, rec=recording, lab=LAB, robot=robot_id) for a in argv]
    got, out, _ = run([*args, "--json"], capsys)
    assert got == code, out
    lines = out.splitlines()
    objects = [json.loads(line) for line in lines]  # every line is one JSON object
    assert objects and all(isinstance(o, dict) for o in objects), out
    assert len(objects) == n_objects if n_objects is not None else len(objects) >= 1
    got, text, err = run(args, capsys)
    text = text if code == 0 else text + err  # a failure is said on stderr
    assert got == code and text.strip(), text
    with pytest.raises(json.JSONDecodeError):  # for people: not JSON
        json.loads(text)


def test_json_of_results_and_text_of_fields() -> None:
    from sofia_schemas.messages import GripperResult

    result = GripperResult(action="open", ok=True, reason="done", opening_mm=100.0)
    value = jsonable({"path": Path("a/b"), "result": result, "v": (1, 2)})
    assert json.loads(json.dumps(value)) == {
        "path": "a/b", "result": result.model_dump(mode="json"), "v": [1, 2],
    }  # fmt: skip
    assert fields_text({"scene": "board", "blob": {"radius": 0.0150000001}, "none": None}) == (
        "scene: board\nblob:\n  radius: 0.015"
    )


def test_arm_and_gripper_results_for_people() -> None:
    """The text the arm and gripper commands print (their --json is the message itself)."""
    from sofia_arm.cli import describe_result, describe_state
    from sofia_gripper.cli import describe_result as describe_gripper
    from sofia_schemas.messages import ArmPhase, ArmResult, ArmState, GripperResult, GripperState

    moved = ArmResult(ok=True, command="pick_place", status="done", duration_s=12.0, position=(0.45, -0.25, 0.25),
                      quaternion_xyzw=(1.0, 0.0, 0.0, 0.0),
                      phases=[ArmPhase(name="grasp", status="done", reason="gripper stalled, grasped True")])  # fmt: skip
    assert describe_result(moved).splitlines() == [
        "pick_place: done, 12.0 s",
        "  flange at [0.4500, -0.2500, 0.2500] m, quaternion x y z w [1.0000, 0.0000, 0.0000, 0.0000] (base frame)",
        "  ok   grasp: gripper stalled, grasped True",
    ]
    state = ArmState(stamp_ns=1, connected=True, mode="idle", q=(0.0,) * 7, errors=[], last_result=moved)
    text = describe_state(state)
    assert text.startswith("arm: connected, mode idle\n") and "errors: none" in text
    assert "joints [0.000, 0.000, 0.000, 0.000, 0.000, 0.000, 0.000] rad" in text
    assert "last command: pick_place: done" in text and "flange at unknown" in text
    grasp = GripperResult(
        action="grasp", ok=True, reason="stalled", grasped=True, opening_mm=39.1, duration_s=0.36
    )
    assert describe_gripper(grasp) == "grasp: stalled, opening 39.1 mm, grasped, 0.36 s"
    gs = GripperState(stamp_ns=1, connected=True, status="ok", current_ma=12.0, torque_enabled=True)
    shown = describe_gripper(GripperResult(action="state", ok=True, reason="done", state=gs))
    assert shown.splitlines()[1:4] == ["  connected: True", "  status: ok", "  torque: on"]
    assert "  current: 12 mA" in shown and "hardware errors: none" in shown
