"""The twin node's health, pacing and command accounting, over real rclpy and FastDDS.

A module of its own (its own ROS context and nodes): the command counts rely on the test's
probe being the only publisher of a command topic, which the module-scoped twin of
test_ros_twin_node.py would not leave true. Helpers and fixtures are shared with it.
"""
from __future__ import annotations

import math

import numpy as np
from test_ros_twin_node import (WAIT_S, _finite, ros, stamp_ns,  # noqa: F401 (fixtures)
                                twin_factory)

from drill_twin import interface as itf


def _values(status) -> dict:
    return {kv.key: kv.value for kv in status.values}


def _health_after(twin, count: int, condition=lambda status: True, what='a health report'):
    """Spin until a health report after the first ``count`` satisfies ``condition``."""
    def found():
        return [s for s in twin.statuses('drill_twin: twin health')[count:] if condition(s)]
    twin.spin_until(found, what)
    return found()[0]


def test_health_tells_the_truth(twin_factory):  # noqa: F811
    """OK only while nothing goes wrong.

    A rejected command makes the next report WARN; a mean model breaking a physical bound (3 MN
    let past the door) makes it ERROR, held in the report after too, with every reason in the
    status itself; then OK again. Nothing implausible is published meanwhile. The drum's brake
    would hold that string to 1 m/s: it is off here (the paper's bare hook force).
    """
    from diagnostic_msgs.msg import DiagnosticStatus

    twin = twin_factory(ensemble_members=0, health_rate_hz=20.0, log_enabled=False,
                        model_overrides=['drawworks.block_speed_max_m_per_s=null'])
    node = twin.node
    ok = _health_after(twin, 0, lambda s: s.level == DiagnosticStatus.OK, 'an OK report')
    assert ok.message == 'running'
    twin.command(itf.CMD_HOOK_LOAD, math.nan)
    seen = len(twin.statuses('drill_twin: twin health'))
    warn = _health_after(twin, seen, lambda s: s.level != DiagnosticStatus.OK, 'a WARN report')
    assert warn.level == DiagnosticStatus.WARN and '1 command(s) rejected' in warn.message
    assert 'not a finite number' in _values(warn)['reason_1']
    _health_after(twin, seen, lambda s: s.level == DiagnosticStatus.OK, 'OK again')

    hook = node.engine.hook_load_command
    seen = len(twin.statuses('drill_twin: twin health'))
    broken = node.health.latest.get('mean_model_implausible_steps', 0)
    node.engine.rig.set_hook_load(3.0e6)                     # past the door
    # Until the guard has caught it once (twin steps, not a wall-clock health period).
    twin.spin_until(lambda: node.health.latest.get('mean_model_implausible_steps', 0) > broken,
                    'an implausible step')
    node.engine.rig.set_hook_load(hook)
    error = _health_after(twin, seen, lambda s: s.level == DiagnosticStatus.ERROR, 'an ERROR')
    assert 'the mean model broke a physical bound' in error.message
    assert 'beyond' in _values(error)['reason_1']
    reports = twin.statuses('drill_twin: twin health')
    index = reports.index(error)
    _health_after(twin, index + 1, lambda s: s.level == DiagnosticStatus.OK, 'OK after it')
    reports = twin.statuses('drill_twin: twin health')
    assert reports[index + 1].level == DiagnosticStatus.ERROR          # held one period
    guard = node.engine._mean.guard
    hole = float(node.engine.simulator.hole_depth_m[0])      # the restarts drill a little
    assert hole <= 1600.05
    for m in twin.received[itf.BIT_STATE]:
        assert 0.0 <= m.position[0] <= hole + guard.bit_penetration_m
        assert abs(m.velocity[0]) <= guard.axial_speed_max_m_per_s
    for topic in (itf.KPI_STICK_SLIP, itf.KPI_MSE, itf.KPI_ROP):
        assert _finite([m.data for m in twin.received[topic]])


def test_health_comes_while_the_twin_clock_stands_still(twin_factory):  # noqa: F811
    """Health has a wall-clock timer of its own.

    With the tick timer stopped (the twin's clock stands still) reports still come, and say so.
    """
    from diagnostic_msgs.msg import DiagnosticStatus

    twin = twin_factory(ensemble_members=0, health_rate_hz=10.0, log_enabled=False)
    twin.spin_to(0.1)
    twin.node.timer.cancel()
    seen = len(twin.statuses('drill_twin: twin health'))
    frozen = _health_after(twin, seen, lambda s: 'has not advanced' in s.message,
                           'a report of the frozen clock')
    assert frozen.level == DiagnosticStatus.WARN
    # From the frozen report on (a report in flight when the timer stopped may predate the
    # last tick), the twin's time stands.
    reports = twin.statuses('drill_twin: twin health')
    _health_after(twin, reports.index(frozen) + 1, what='a report after it')
    later = twin.statuses('drill_twin: twin health')[reports.index(frozen):]
    assert len(later) >= 2 and len({_values(s)['sim_time_s'] for s in later}) == 1


def test_the_real_time_twin_never_runs_ahead_of_the_wall_clock(twin_factory):  # noqa: F811
    """Steps of 50 ms at 100 Hz ticks.

    Each step is taken when the wall clock reaches it, so no stamp is ever later than the ROS
    time at which the probe hears it.
    """
    from sensor_msgs.msg import JointState

    twin = twin_factory(fast=False, ensemble_members=0, time_step_s=0.05, rate_hz=100.0,
                        log_enabled=False)
    heard = []
    clock = twin.probe.get_clock()
    twin.probe.create_subscription(
        JointState, itf.BIT_STATE,
        lambda m: heard.append((stamp_ns(m), clock.now().nanoseconds)), 100)
    twin.spin_until(lambda: len(heard) >= 20, 'twenty 50 ms steps')
    assert all(stamp <= at for stamp, at in heard)
    steps = np.diff([stamp for stamp, _ in heard]) / 50_000_000
    assert np.all(steps >= 1) and np.all(steps == np.round(steps))    # whole 50 ms steps


def test_commands_are_counted_dropped_and_superseded(twin_factory):  # noqa: F811
    """One command, heard.

    Then 3000 in a burst while the twin does not spin: its queue (keep last 1000) keeps the last
    1000, the gap in the publisher's sequence numbers counts the others as dropped; of those
    taken between two ticks only the last takes effect, the rest are superseded (real time: 100
    ticks a second, the commands are taken much faster). Health reports every count and WARNs of
    the drops.
    """
    from diagnostic_msgs.msg import DiagnosticStatus

    # The probe hears the bit state and the reports alone: its executor turns stay short, and
    # many commands are taken between two ticks however busy the machine.
    twin = twin_factory(ensemble_members=0, health_rate_hz=20.0, log_enabled=False, fast=False,
                        topics=(itf.BIT_STATE, itf.DIAGNOSTICS))
    node = twin.node
    twin.spin_to(0.05)
    hook = node.engine.hook_load_command
    twin.command(itf.CMD_HOOK_LOAD, hook - 1e3)
    twin.spin_until(lambda: node.engine.commands_received == 1, 'the first command')
    sent = 3000
    seen = len(twin.statuses('drill_twin: twin health'))
    for k in range(sent):
        twin.command(itf.CMD_HOOK_LOAD, hook - 2e3 - k)
    twin.spin_until(lambda: node.engine.hook_load_command == hook - 2e3 - (sent - 1),
                    'the last command')
    received, dropped = node.engine.commands_received, node.intake.dropped
    assert received + dropped == sent + 1 and dropped > 0
    assert 0 < node.intake.superseded < received - 1
    warned = _health_after(twin, seen, lambda s: 'dropped' in s.message, 'the drops reported')
    assert warned.level == DiagnosticStatus.WARN
    final = _health_after(twin, seen, lambda s: _values(s)['commands_received'] == str(received),
                          'a report after the burst')
    values = _values(final)
    assert int(values['commands_dropped']) == dropped
    assert int(values['commands_superseded']) == node.intake.superseded > 0


def test_the_stop_future_does_not_collect_callbacks(ros):  # noqa: F811
    """The stop future keeps one wake-up callback however long it is awaited.

    The node's ``done`` future awaited by Executor.spin_until_future_complete (as
    ``drill-twin twin`` does) for 300 turns keeps one wake-up callback, not one per turn,
    per waiting function (rclpy 7.1 adds a fresh one every turn: the node's memory grew
    1.2 MB/min).
    """
    from rclpy.executors import SingleThreadedExecutor

    from drill_twin.ros.twin_node import StopFuture

    node = ros.create_node('stop_future_probe')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    done, held = StopFuture(), []

    def tick():
        if len(held) == 300:
            done.set_result(True)
        else:
            held.append(len(done._callbacks))

    node.create_timer(1e-4, tick)
    try:
        executor.spin_until_future_complete(done, timeout_sec=WAIT_S)
    finally:
        executor.shutdown()
        node.destroy_node()
    assert done.done() and len(held) == 300
    assert max(held) <= 2 and held[-1] == held[0]
