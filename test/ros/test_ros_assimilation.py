"""The twin node assimilating a rig's measurements, over real rclpy and FastDDS.

A module of its own (its own ROS context): a probe publishes the rig's sensor messages
(sensor_msgs/JointState, as docs/ASSIMILATION.md lays them out) to a fast twin whose ensemble
is an ensemble Kalman filter, and hears what the twin publishes.
"""
from __future__ import annotations

import math

import numpy as np
from test_ros_twin_node import ros, stamp_ns, twin_factory  # noqa: F401 (fixtures)

from drill_twin import interface as itf


def _values(status) -> dict:
    return {kv.key: kv.value for kv in status.values}


def _rig_publishers(twin):
    from sensor_msgs.msg import JointState

    from drill_twin.recording.qos import rclpy_qos_profile
    publishers = {topic: twin.probe.create_publisher(JointState, topic,
                                                     rclpy_qos_profile(itf.STATE_QOS))
                  for topic in ('/rig/top_drive', '/rig/hook')}
    twin.spin_until(lambda: all(p.get_subscription_count() for p in publishers.values()),
                    'the twin subscribing to the rig')
    return publishers


def _reading(stamp, name, position=(), velocity=(), effort=()):
    from sensor_msgs.msg import JointState
    message = JointState(name=[name], position=list(position), velocity=list(velocity),
                         effort=list(effort))
    message.header.stamp.sec, message.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
    return message


def _feeder(twin, rig, torque_offset_nm: float = 0.0):
    """
    Return a function that sends the rig's reading of the latest top state heard (10 Hz).

    ``rig``: the publishers by topic; with '/rig/block_position' (std_msgs/Float64) the block
    position goes there, else with the hook load in the hook's JointState.
    """
    from std_msgs.msg import Float64
    sent = 0

    def feed():
        nonlocal sent
        tops = twin.received[itf.TOP_STATE]
        if not tops or stamp_ns(tops[-1]) < (sent + 1) * 100_000_000:
            return False
        top = tops[-1]
        sent = stamp_ns(top) // 100_000_000
        torque, block = top.effort[0] + torque_offset_nm, top.position[1]
        rig['/rig/top_drive'].publish(_reading(stamp_ns(top), 'top_drive',
                                               velocity=[top.velocity[0]], effort=[torque]))
        if '/rig/block_position' in rig:
            rig['/rig/block_position'].publish(Float64(data=float(block)))
        else:
            rig['/rig/hook'].publish(_reading(stamp_ns(top), 'hook', position=[block],
                                              effort=[top.effort[1]]))
        return False
    return feed


def test_the_twin_assimilates_the_rigs_surface_measurements(twin_factory, tmp_path):  # noqa: F811
    """
    The rig's surface torque and block position are analysed.

    Here the mean model's own, as a rig whose string is the mean model would read them: the
    estimated germ is published
    with bounds after the first analyses, health reports the analyses, the NIS and the samples
    used; the samples are in the log; a malformed message and a NaN reading are refused with
    their reasons (WARN), and the twin goes on.
    """
    from diagnostic_msgs.msg import DiagnosticStatus

    # The analyses written at once, so that the members' germs equal the last published one
    # when the twin stands still (in parts, the record is the analysis, which the members
    # reach within the increment: test_analysis_increment.py).
    twin = twin_factory(ensemble_members=6, ensemble_dispersion=0.2, ensemble_process=False,
                        assimilation_enabled=True, health_rate_hz=5.0, duration_s=0.0,
                        log_dir=tmp_path / 'logs',
                        assimilation_overrides=['assimilation.filter.increment_duration_s=0.0'])
    rig = _rig_publishers(twin)
    assert set(twin.node.measurement_topics) == {'/rig/top_drive', '/rig/hook'}
    feed = _feeder(twin, rig)

    twin.spin_until(lambda: feed() or len(twin.received[itf.ASSIMILATION_GERM_MEAN]) >= 5,
                    'five estimated germs')
    twin.node.timer.cancel()                        # the twin stands still: hear all it sent
    for _ in range(20):
        twin.executor.spin_once(timeout_sec=0.05)
    mean = np.array([m.data for m in twin.received[itf.ASSIMILATION_GERM_MEAN]])
    lower = np.array([m.data for m in twin.received[itf.ASSIMILATION_GERM_LOWER]])
    upper = np.array([m.data for m in twin.received[itf.ASSIMILATION_GERM_UPPER]])
    assert mean.shape[1] == 3 and np.all(np.isfinite(mean))
    n = min(len(mean), len(lower), len(upper))
    assert np.all(lower[:n] <= mean[:n] + 1e-12) and np.all(mean[:n] <= upper[:n] + 1e-12)
    assert np.all(mean[:, [0, 2]] > 0)                                 # G11, G22 of an SPD germ
    germ = twin.node.engine.ensemble_runner.simulator.integrator.germ
    np.testing.assert_allclose(mean[-1], [germ[:, 0, 0].mean(), germ[:, 0, 1].mean(),
                                          germ[:, 1, 1].mean()], rtol=1e-9)

    def report(condition, what, seen=None):
        """Spin until a health report after the first ``seen`` (default: now) meets it."""
        seen = len(twin.statuses('drill_twin: twin health')) if seen is None else seen
        found = []

        def check():
            feed()
            found[:] = [s for s in twin.statuses('drill_twin: twin health')[seen:]
                        if condition(s)]
            return bool(found)
        twin.spin_until(check, what)
        return found[0]

    twin.node.timer.reset()
    status = report(lambda s: int(_values(s).get('assimilation_analyses', 0)) > 0,
                    'a report with analyses')
    values = _values(status)
    assert math.isfinite(float(values['nis_per_measurement']))
    assert int(values['measurements_used']) > 0 and int(values['measurements_refused']) == 0

    # A message without its joint, and a NaN torque: refused with why; the twin goes on.
    seen = len(twin.statuses('drill_twin: twin health'))
    now = twin.node.clock.twin_time_ns()
    rig['/rig/top_drive'].publish(_reading(now, 'kelly', velocity=[1.0], effort=[1.0]))
    rig['/rig/top_drive'].publish(_reading(now, 'top_drive', velocity=[1.0],
                                           effort=[math.nan]))

    def reasons():                                  # every event, with why
        return ' '.join(_values(s)['reason']
                        for s in twin.statuses('drill_twin: measurement rejected'))
    # Each refusal comes with the tick after it; a health report may come between the two.
    twin.spin_until(lambda: feed() or ('carries none of its measurements' in reasons()
                                       and 'is not finite' in reasons()), 'both refusals')
    warn = report(lambda s: s.level == DiagnosticStatus.WARN
                  and 'measurement sample(s) refused' in s.message, 'a WARN on the refusal',
                  seen)
    refused = twin.statuses('drill_twin: measurement rejected')
    assert all(s.level == DiagnosticStatus.WARN for s in refused)
    assert int(_values(warn)['measurements_refused']) >= 1
    before = twin.node.engine.time_s
    twin.spin_until(lambda: feed() or twin.node.engine.time_s > before + 0.5, 'the twin going on')

    # The rig's samples are in the twin's log, as received.
    twin.node.close()
    from drill_twin.recording.reader import iter_raw
    logs = sorted((tmp_path / 'logs').glob('*/*.mcap'))
    topics = {}
    for path in logs:
        for _, channel, _ in iter_raw(path):
            topics[channel.topic] = topics.get(channel.topic, 0) + 1
    assert topics.get('/rig/top_drive', 0) >= 5 and topics.get('/rig/hook', 0) >= 5
    assert topics.get(itf.ASSIMILATION_GERM_MEAN, 0) >= 5
    # The log says the ensemble assimilated: a resimulation reproduces the mean model only.
    from drill_twin.recording.resimulate import resimulate
    result = resimulate(logs[0].parent)
    assert result.assimilated and result.ensemble_compared == 0
    assert result.compared > 20 and result.identical


def test_without_measurements_the_twin_says_it_runs_in_open_loop(twin_factory):  # noqa: F811
    from diagnostic_msgs.msg import DiagnosticStatus

    twin = twin_factory(ensemble_members=4, ensemble_process=False, assimilation_enabled=True,
                        health_rate_hz=5.0, log_enabled=False)
    seen = 1

    def warned():
        return [s for s in twin.statuses('drill_twin: twin health')[seen:]
                if s.level == DiagnosticStatus.WARN and 'open loop' in s.message]
    twin.spin_until(warned, 'a WARN saying the ensemble runs in open loop')
    assert 'no measurement sample arrived on /rig/top_drive, /rig/hook' in warned()[0].message


def test_the_twin_publishes_the_estimated_sensor_bias(twin_factory, tmp_path):  # noqa: F811
    """
    With a channel's bias_prior_std in assimilation_config its bias is estimated and published.

    The rig reads the mean model's surface torque 300 N m high: three estimates on
    /drill_twin/assimilation/bias/{mean,lower,upper}, labelled 'top_torque', the last one
    the filter's members' mean, and moved towards the offset from the centred prior.
    """
    settings = tmp_path / 'assimilation.yaml'
    settings.write_text('assimilation:\n'
                        '  filter: {measurements: [top_torque, block_position, torque_on_bit]}\n'
                        '  channels:\n    top_torque: {bias_prior_std: 200.0}\n')
    twin = twin_factory(ensemble_members=6, ensemble_dispersion=0.2, ensemble_process=False,
                        assimilation_enabled=True, assimilation_config=str(settings),
                        duration_s=0.0, log_enabled=False)
    feed = _feeder(twin, _rig_publishers(twin), torque_offset_nm=300.0)
    twin.spin_until(lambda: feed() or len(twin.received[itf.ASSIMILATION_BIAS_MEAN]) >= 3,
                    'three estimated biases')
    twin.node.timer.cancel()                        # the twin stands still: hear all it sent
    for _ in range(20):
        twin.executor.spin_once(timeout_sec=0.05)
    means = twin.received[itf.ASSIMILATION_BIAS_MEAN]
    assert all(m.layout.dim[0].label == 'top_torque' for m in means)
    bias = twin.node.engine.ensemble_runner.filter.channel_bias[:, 0]
    assert abs(means[-1].data[0] - bias.mean()) <= 1e-9 * 300
    assert means[-1].data[0] > 50.0                 # from 0 towards the 300 N m offset
    lower = twin.received[itf.ASSIMILATION_BIAS_LOWER][-1].data[0]
    upper = twin.received[itf.ASSIMILATION_BIAS_UPPER][-1].data[0]
    assert lower <= means[-1].data[0] <= upper


def test_a_channel_on_a_float64_topic_is_assimilated(twin_factory, tmp_path):  # noqa: F811
    """
    The block position as std_msgs/Float64 on /rig/block_position (``channels.<c>.topic``).

    The twin subscribes to it instead of the hook's JointState (the filter uses no other hook
    channel), stamps each value when received (the hook's delay is 0) and analyses it: the
    filter uses about two samples per surface torque sent (one of each), and a NaN value is
    refused naming the topic. The values are logged on their topic.
    """
    from diagnostic_msgs.msg import DiagnosticStatus
    from std_msgs.msg import Float64

    from drill_twin.recording.qos import rclpy_qos_profile
    settings = tmp_path / 'assimilation.yaml'
    settings.write_text('assimilation:\n'
                        '  channels:\n    block_position: {topic: /rig/block_position}\n')
    twin = twin_factory(ensemble_members=6, ensemble_dispersion=0.2, ensemble_process=False,
                        assimilation_enabled=True, assimilation_config=str(settings),
                        duration_s=0.0, log_dir=tmp_path / 'logs')
    assert set(twin.node.measurement_topics) == {'/rig/top_drive'}
    assert twin.node.scalar_measurement_topics == {'/rig/block_position': 'block_position'}
    from sensor_msgs.msg import JointState
    rig = {'/rig/top_drive': twin.probe.create_publisher(JointState, '/rig/top_drive',
                                                         rclpy_qos_profile(itf.STATE_QOS)),
           '/rig/block_position': twin.probe.create_publisher(
               Float64, '/rig/block_position', rclpy_qos_profile(itf.STATE_QOS))}
    block = rig['/rig/block_position']
    twin.spin_until(lambda: all(p.get_subscription_count() for p in rig.values()),
                    'the twin subscribing to the rig')
    feed = _feeder(twin, rig)

    sequential = twin.node.engine.ensemble_runner.filter
    offered, offer = [], sequential.offer

    def counted(sample):
        offered.append(sample)
        return offer(sample)
    sequential.offer = counted
    twin.spin_until(lambda: feed() or sequential.analyses >= 2, 'two analyses')
    hook = [s for s in offered if s.sensor == 'hook']
    tops = [s for s in offered if s.sensor == 'top_drive']
    assert len(hook) >= 5 and abs(len(hook) - len(tops)) <= 2
    assert all(set(s.values) == {'block_position'} for s in hook)
    for sample in hook:          # stamped when received: a few ticks after the state it is of
        assert min(abs(sample.stamp_s - t.stamp_s) for t in tops) <= 0.05
    assert sequential.samples_used > len(tops)      # more than the torques alone could be
    assert sequential.samples_refused == 0

    block.publish(Float64(data=math.nan))
    twin.spin_until(lambda: feed() or twin.statuses('drill_twin: measurement rejected'),
                    'the NaN refused')
    refused = twin.statuses('drill_twin: measurement rejected')
    assert refused[0].level == DiagnosticStatus.WARN
    assert '/rig/block_position: block_position = nan is not finite' in _values(
        refused[0])['reason']
    twin.node.close()
    from drill_twin.recording.reader import iter_raw
    logged = [channel.topic for path in sorted((tmp_path / 'logs').glob('*/*.mcap'))
              for _, channel, _ in iter_raw(path)]
    assert logged.count('/rig/block_position') >= 5
