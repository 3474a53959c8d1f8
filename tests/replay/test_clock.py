"""The replayer's clock: log times scaled by the rate, loops that keep each topic's period, resyncs."""

from __future__ import annotations

import pytest
from sofia_replay.clock import RESYNC_LAG_S, SINGLE_LOOP_NS, PlayClock, loop_span_ns

T0 = 1_700_000_000_000_000_000
PERIOD = 50_000_000  # 20 Hz
N = 8


def test_loop_span_keeps_each_topics_period() -> None:
    one = {"/points": (T0, T0 + (N - 1) * PERIOD, N)}
    assert loop_span_ns(one) == N * PERIOD
    # clouds and poses interleaved (a pose 10 ms after each cloud) and one static transform: the
    # clouds' period holds across the wrap, not the mean interval of all messages (~half of it)
    mixed = {
        "/points": (T0, T0 + (N - 1) * PERIOD, N),
        "/pose": (T0 + 10_000_000, T0 + 10_000_000 + (N - 1) * PERIOD, N),
        "/tf_static": (T0, T0, 1),
    }
    assert loop_span_ns(mixed) == N * PERIOD
    # a 1 kHz topic and a 20 Hz one: the longer loop, so that the 20 Hz topic does not burst
    fast = {"/points": (T0, T0 + (N - 1) * PERIOD, N), "/joints": (T0, T0 + 350_000_000, 351)}
    assert loop_span_ns(fast) == N * PERIOD
    assert loop_span_ns({"/a": (T0, T0, 1)}) == SINGLE_LOOP_NS  # one message: once a second
    assert loop_span_ns({"/a": (T0, T0, 3)}) == SINGLE_LOOP_NS  # all at one time: no hot loop
    assert loop_span_ns({}) == SINGLE_LOOP_NS


def test_second_loop_follows_the_first_by_one_period() -> None:
    """At twice the recorded speed, message i of loop k is due (k N + i) periods / 2 after the first."""
    clock = PlayClock(rate=2.0)
    now = 100.0
    for i in range(N):
        delay = clock.delay_s("/points", T0 + i * PERIOD, now)
        assert delay == pytest.approx(i * PERIOD / 2e9)
    clock.next_loop()
    assert clock.delay_s("/points", T0, now) == pytest.approx(N * PERIOD / 2e9)  # one period after the last
    assert clock.delay_s("/points", T0 + PERIOD, now) == pytest.approx((N + 1) * PERIOD / 2e9)
    clock.next_loop()  # the second loop (2 messages, one period apart) is measured anew
    assert clock.delay_s("/points", T0, now) == pytest.approx((N + 2) * PERIOD / 2e9)
    assert clock.resyncs == 0


def test_late_message_restarts_the_clock_instead_of_bursting() -> None:
    clock = PlayClock(rate=1.0)
    clock.delay_s("/points", T0, 100.0)
    late = 100.0 + RESYNC_LAG_S + 0.1  # a stall: the message at +1 period is put this late
    assert clock.delay_s("/points", T0 + PERIOD, late) == 0.0 and clock.resyncs == 1
    assert clock.delay_s("/points", T0 + 2 * PERIOD, late) == pytest.approx(PERIOD / 1e9)  # the period again
    slightly = 100.0 + RESYNC_LAG_S - 0.1 + 4 * PERIOD / 1e9  # behind by less: kept, no resync
    clock.delay_s("/points", T0 + 4 * PERIOD, slightly)
    assert clock.resyncs == 1
