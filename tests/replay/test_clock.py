"""The replayer's clock: log times scaled by the rate, loops that keep the period, resyncs."""

from __future__ import annotations

import pytest
from sofia_replay.clock import RESYNC_LAG_S, SINGLE_LOOP_NS, PlayClock, loop_span_ns

T0 = 1_700_000_000_000_000_000
PERIOD = 50_000_000  # 20 Hz
N = 8


def test_loop_span_is_the_recording_plus_one_period() -> None:
    assert loop_span_ns(T0, T0 + (N - 1) * PERIOD, N) == N * PERIOD
    assert loop_span_ns(T0, T0, 1) == SINGLE_LOOP_NS  # one message: once a second
    assert loop_span_ns(T0, T0, 3) == SINGLE_LOOP_NS  # all at one time: no hot loop
    assert loop_span_ns(None, None, 0) == SINGLE_LOOP_NS


def test_second_loop_follows_the_first_by_one_period() -> None:
    """At twice the recorded speed, message i of loop k is due (k N + i) periods / 2 after the first."""
    clock = PlayClock(rate=2.0)
    now = 100.0
    assert clock.delay_s(T0, now) == 0.0  # the first message sets the origin
    last = T0 + (N - 1) * PERIOD
    assert clock.delay_s(last, now) == pytest.approx((N - 1) * PERIOD / 2e9)
    clock.next_loop(T0, last, N)
    assert clock.delay_s(T0, now) == pytest.approx(N * PERIOD / 2e9)  # one period after the last
    assert clock.delay_s(T0 + PERIOD, now) == pytest.approx((N + 1) * PERIOD / 2e9)
    assert clock.resyncs == 0


def test_late_message_restarts_the_clock_instead_of_bursting() -> None:
    clock = PlayClock(rate=1.0)
    clock.delay_s(T0, 100.0)
    late = 100.0 + RESYNC_LAG_S + 0.1  # a stall: the message at +1 period is put this late
    assert clock.delay_s(T0 + PERIOD, late) == 0.0 and clock.resyncs == 1
    assert clock.delay_s(T0 + 2 * PERIOD, late) == pytest.approx(PERIOD / 1e9)  # the period again
    slightly = 100.0 + RESYNC_LAG_S - 0.1 + 4 * PERIOD / 1e9  # behind by less: kept, no resync
    clock.delay_s(T0 + 4 * PERIOD, slightly)
    assert clock.resyncs == 1
