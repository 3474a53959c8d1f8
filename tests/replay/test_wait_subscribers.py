"""``--wait-subscribers``: the player waits until every key it plays has a subscriber, and plays anyway
(with a warning) when none comes within the time given."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import zenoh
from sofia_replay.player import Player, PlayOptions
from sofia_schemas import Keys
from sofia_schemas.keys import TOPIC_POINTS

from .test_play import recording  # noqa: F401 - the fixture

SUBSCRIBER_AFTER_S = 0.5


def test_waits_until_a_subscriber_appears(
    recording: tuple[Path, dict[str, list[bytes]]],  # noqa: F811
    session: zenoh.Session, collect: Callable[[str], Any], robot_id: str,
) -> None:  # fmt: skip
    """A subscriber declared (by another session) only after the wait began: the wait ends once it
    is known, not before."""
    player = Player(
        session, recording[0], robot_id, PlayOptions(topics=[TOPIC_POINTS], wait_subscribers_s=20)
    )
    late = threading.Timer(SUBSCRIBER_AFTER_S, collect, (Keys(robot_id).points,))
    try:
        t0 = time.monotonic()
        late.start()
        assert player.wait_for_subscribers(threading.Event())  # type: ignore[arg-type]
        assert time.monotonic() - t0 >= SUBSCRIBER_AFTER_S
    finally:
        late.join()
        player.close()


def test_plays_anyway_when_no_subscriber_comes(
    recording: tuple[Path, dict[str, list[bytes]]],  # noqa: F811
    session: zenoh.Session, robot_id: str, caplog: pytest.LogCaptureFixture,
) -> None:  # fmt: skip
    wait_s = 0.4
    player = Player(
        session, recording[0], robot_id, PlayOptions(topics=[TOPIC_POINTS], wait_subscribers_s=wait_s)
    )
    try:
        t0 = time.monotonic()
        with caplog.at_level(logging.WARNING, logger="sofia_replay.player"):
            assert not player.wait_for_subscribers(threading.Event())  # type: ignore[arg-type]
        assert time.monotonic() - t0 >= wait_s
        assert f"no subscriber on ['{Keys(robot_id).points}'] after {wait_s} s, playing anyway" in caplog.text
    finally:
        player.close()
