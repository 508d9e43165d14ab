"""What a tick's messages are: the topics a caller wants, built by the node's own code."""
from __future__ import annotations

from types import SimpleNamespace

from synthetic import _snapshot

from drill_twin import interface as itf
from drill_twin.ros import messages

STATIONS_M = (500.0, 1000.0)
PLAN = messages.TickPlan(kpis=True, ensemble_stamp_ns=7, clock=True)


def a_snapshot():
    """Return a snapshot of the synthetic stick-slip signals (surface readings, ensemble)."""
    state = {'angle': 0.0, 'depth': 1500.0, 'dt': 0.01, 'every_second': 100}
    return _snapshot(0.37, 37, STATIONS_M, state)


def test_the_wanted_topics_are_those_of_the_whole_tick_in_its_order():
    snapshot = a_snapshot()
    every = messages.tick_messages(snapshot, STATIONS_M, 10, PLAN)
    topics = [topic for topic, _ in every]
    assert len(topics) == len(set(topics))
    assert {itf.BIT_STATE, itf.CLOCK, itf.KPI_ROP, itf.vibration_imu_topic(1000.0),
            *itf.SURFACE_TOPICS} <= set(topics)
    # Every other topic, one station's two, a surface reading, a KPI and /clock.
    chosen = set(topics[::2]) | {itf.vibration_imu_topic(1000.0),
                                 itf.vibration_displacement_topic(1000.0),
                                 itf.SURFACE_WOB, itf.KPI_ROP, itf.CLOCK}
    some = messages.tick_messages(snapshot, STATIONS_M, 10, PLAN, chosen.__contains__)
    assert [topic for topic, _ in some] == [topic for topic in topics if topic in chosen]
    whole = dict(every)
    for topic, message in some:
        assert message == whole[topic], topic
    assert messages.tick_messages(snapshot, STATIONS_M, 10, PLAN, lambda topic: False) == []


def test_a_state_nobody_wants_is_not_built():
    """The every-tick states of the unwanted topics are not made (the node's saving).

    The snapshot lacks what the unwanted messages would read (the top, the contacts, the
    stations' accelerations and spin): building one of them fails.
    """
    snapshot = a_snapshot()
    kept = ('station_displacement_m',)
    observation = {name: value for name, value in vars(snapshot.observation).items()
                   if name in kept or not name.startswith(('station_', 'top_', 'hook_',
                                                           'contact_'))}
    assert len(observation) < len(vars(snapshot.observation))
    bare = SimpleNamespace(**dict(vars(snapshot), observation=SimpleNamespace(**observation)))
    wanted = {itf.BIT_STATE, itf.vibration_displacement_topic(500.0)}.__contains__
    some = messages.tick_messages(bare, STATIONS_M, 10, messages.TickPlan(), wanted)
    assert [topic for topic, _ in some] == [itf.BIT_STATE, itf.vibration_displacement_topic(500.0)]
    assert some == [(topic, message) for topic, message
                    in messages.tick_messages(snapshot, STATIONS_M, 10, messages.TickPlan())
                    if wanted(topic)]
