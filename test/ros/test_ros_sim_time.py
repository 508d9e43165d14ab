"""use_sim_time: the twin follows an external /clock (a probe node publishes it), and TF.

The twin node and a probe on one executor over real rclpy (fixtures of test_ros_twin_node).
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from test_ros_twin_node import ros, stamp_ns, twin_factory  # noqa: F401 (fixtures)

from drill_twin import interface as itf

EPOCH_NS = 50_000_000_000                 # the external clock's first time: 50 s


def _clock(time_ns: int):
    from rosgraph_msgs.msg import Clock

    from drill_twin.ros.messages import stamp

    return Clock(clock=stamp(time_ns))


def test_use_sim_time_follows_an_external_clock(twin_factory):  # noqa: F811
    """With use_sim_time the twin follows an external /clock.

    It waits for /clock, starts its clock at the first message, steps to each received time
    and never past it, stamps its messages with that clock, logs it as the epoch, and
    publishes no /clock itself.
    """
    from drill_twin.recording.qos import rclpy_qos_profile
    from drill_twin.recording.reader import read_metadata

    twin = twin_factory(fast=False, use_sim_time=True, ensemble_members=0, health_rate_hz=5.0)
    node, probe = twin.node, twin.probe
    assert itf.CLOCK not in node.outputs.publishers
    clock = probe.create_publisher(type(_clock(0)), itf.CLOCK,
                                   rclpy_qos_profile(itf.CLOCK_QOS))
    twin.spin_until(lambda: clock.get_subscription_count() >= 2,      # the twin's, rclpy's
                    'the twin subscribed to /clock')

    # No /clock yet: the twin does not step, opens no log, and says it is waiting.
    twin.spin_until(lambda: twin.statuses('drill_twin: twin health'), 'a health report')
    assert node.engine.step_index == 0 and node.log is None
    assert 'waiting for the first /clock' in twin.statuses('drill_twin: twin health')[-1].message

    def follow(time_ns: int) -> None:
        steps = (time_ns - EPOCH_NS) // node.clock.dt_ns

        def reached():
            clock.publish(_clock(time_ns))                   # best effort: say it again
            return node.engine.step_index >= steps and twin.received[itf.BIT_STATE] and (
                stamp_ns(twin.received[itf.BIT_STATE][-1]) == time_ns)
        twin.spin_until(reached, f'the twin at /clock {time_ns * 1e-9} s')
        for _ in range(30):                                  # and it stays there
            clock.publish(_clock(time_ns))
            twin.executor.spin_once(timeout_sec=0.01)
        assert node.engine.step_index == steps

    twin.spin_until(lambda: clock.publish(_clock(EPOCH_NS)) or node.clock.started,
                    'the first /clock')
    assert node.clock.epoch_ns == EPOCH_NS
    follow(EPOCH_NS + 250_000_000)
    follow(EPOCH_NS + 400_000_000)
    stamps = np.array([stamp_ns(m) for m in twin.received[itf.BIT_STATE]])
    assert stamps[0] > EPOCH_NS and np.all(np.diff(stamps) > 0)
    assert stamps[-1] == EPOCH_NS + 400_000_000
    assert np.all(stamps % node.clock.dt_ns == 0)                  # whole steps from the epoch
    publishers = {info.node_name for info in probe.get_publishers_info_by_topic(itf.CLOCK)}
    assert publishers == {'twin_probe'}
    assert node.log is not None
    record = read_metadata(node.log.split_path)['drill_twin']
    assert int(record['clock_epoch_ns']) == EPOCH_NS and record['fast'] == 'false'


def test_twin_frames_follow_rep_103_and_the_string():
    """The hole frame is the rig frame turned so that x points down.

    The top and the bit move along it with the top's displacement and the bit's depth; stations
    hang below the top.
    """
    from drill_twin.ros import messages

    def rotate(q, v):
        x, y, z, w = q
        u = np.array([x, y, z])
        v = np.asarray(v, dtype=float)
        return v + 2 * w * np.cross(u, v) + 2 * np.cross(u, np.cross(u, v))

    static = {t.child_frame_id: t for t in messages.static_transforms((700.0, 1590.0), 7)}
    hole = static[itf.FRAME_HOLE]
    assert hole.header.frame_id == itf.FRAME_RIG and hole.header.stamp.nanosec == 7
    q = hole.transform.rotation
    quaternion = (q.x, q.y, q.z, q.w)
    np.testing.assert_allclose(rotate(quaternion, [1, 0, 0]), [0, 0, -1], atol=1e-15)
    np.testing.assert_allclose(np.cross(rotate(quaternion, [1, 0, 0]),
                                        rotate(quaternion, [0, 1, 0])),
                               rotate(quaternion, [0, 0, 1]), atol=1e-15)   # right-handed
    for x_m in (700.0, 1590.0):
        station = static[itf.station_frame(x_m)]
        assert station.header.frame_id == itf.FRAME_TOP
        assert station.transform.translation.x == x_m
    snapshot = SimpleNamespace(observation=SimpleNamespace(hook_position_m=np.array([0.25])),
                               bit=SimpleNamespace(depth_m=1601.5))
    moving = {t.child_frame_id: t for t in messages.moving_transforms(snapshot, 9)}
    assert moving[itf.FRAME_TOP].header.frame_id == itf.FRAME_HOLE
    assert moving[itf.FRAME_TOP].transform.translation.x == 0.25
    assert moving[itf.FRAME_BIT].header.frame_id == itf.FRAME_HOLE
    assert moving[itf.FRAME_BIT].transform.translation.x == 1601.5


def test_tf_is_published_where_tf2_msgs_is_installed(twin_factory):  # noqa: F811
    """TF is published where tf2_msgs is installed.

    With it, /tf_static (transient local) and /tf reach a subscriber; without it (the PyPI ROS
    wheels), no TF publisher, and the start line says why.
    """
    from drill_twin.ros import messages

    twin = twin_factory(ensemble_members=0)
    node = twin.node
    if messages.TFMessage is None:
        assert not {itf.TF, itf.TF_STATIC} & set(node.outputs.publishers)
        twin.spin_until(lambda: twin.rosout(containing='no TF (tf2_msgs is not installed)'),
                        'the start line saying there is no TF')
        return
    twin.spin_to(0.5)
    static = [t for m in twin.received[itf.TF_STATIC] for t in m.transforms]
    moving = [t for m in twin.received[itf.TF] for t in m.transforms]
    assert {t.child_frame_id for t in static} >= {itf.FRAME_HOLE}
    bits = [t for t in moving if t.child_frame_id == itf.FRAME_BIT]
    assert bits and all(abs(t.transform.translation.x - 1600.0) < 5.0 for t in bits)


def test_contact_forces_layout_is_labelled():
    from drill_twin.ros import messages

    forces = np.array([[0.0, 10.0, 0.0, 5.0]])
    message = messages.contact_forces(SimpleNamespace(
        observation=SimpleNamespace(contact_force_n=forces)))
    (dim,) = message.layout.dim
    assert dim.label == itf.CONTACT_FORCES_LABEL and dim.size == 4 and dim.stride == 4
    assert message.layout.data_offset == 0 and list(message.data) == [0.0, 10.0, 0.0, 5.0]


def test_docs_list_the_contact_force_nodes_of_the_shipped_configuration(default_config):
    from pathlib import Path

    from drill_twin.ros.build import contact_node_depths_m, contact_nodes_markdown

    depths = contact_node_depths_m(default_config)
    assert depths[0] == 0.0 and abs(depths[-1] - default_config.length_m) < 1e-9
    assert np.all(np.diff(depths) > 0)
    text = (Path(__file__).resolve().parents[2] / 'docs' / 'ROS-INTERFACE.md').read_text()
    assert contact_nodes_markdown(default_config) in text, 'regenerate with contact_nodes_markdown'
