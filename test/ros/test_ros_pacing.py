"""The twin's pace (drill_twin.ros.pacing), without ROS: steps per tick for each clock."""
import pytest

from drill_twin.ros.pacing import EXTERNAL_CATCH_UP_TICKS, Pacer

DT = 10_000_000                                  # 10 ms steps


def test_fast_takes_a_tick_every_tick():
    pacer = Pacer('fast', DT, 2, 0)
    assert [pacer.steps(None, k) for k in range(3)] == [2, 2, 2]
    assert pacer.behind(None, 0) == 0


def test_wall_never_runs_ahead_and_catches_up_two_ticks_at_a_time():
    pacer = Pacer('wall', DT, 1, epoch_ns=1_000 * DT)
    # First tick 5 steps after the epoch: the start-up does not count, one step is due.
    assert pacer.steps(1_005 * DT, 0) == 1
    assert pacer.steps(1_005 * DT, 1) == 0                   # the clock has not moved
    assert pacer.steps(1_005 * DT + DT // 2, 1) == 0         # half a step: not yet
    assert pacer.steps(1_006 * DT, 1) == 1
    assert pacer.behind(1_036 * DT, 2) == 30                  # a 0.3 s stall
    assert pacer.steps(1_036 * DT, 2) == 2                    # made up two steps a tick


def test_external_waits_for_the_first_clock_and_follows_it():
    pacer = Pacer('external', DT, 1, epoch_ns=None)
    assert not pacer.started and pacer.steps(None, 0) == 0 and pacer.steps(123, 0) == 0
    pacer.start(50 * 10 ** 9)
    pacer.start(60 * 10 ** 9)                                  # only the first counts
    assert pacer.epoch_ns == 50 * 10 ** 9
    now = 50 * 10 ** 9 + 3 * DT
    assert pacer.steps(now, 0) == 3 and pacer.steps(now, 3) == 0
    far = 50 * 10 ** 9 + 1000 * DT
    assert pacer.steps(far, 3) == EXTERNAL_CATCH_UP_TICKS
    assert pacer.behind(50 * 10 ** 9, 3) == -3                # the clock went back
    assert pacer.steps(50 * 10 ** 9, 3) == 0


def test_bad_pace_is_refused():
    with pytest.raises(ValueError, match='pace must be one of'):
        Pacer('slow', DT, 1, 0)
