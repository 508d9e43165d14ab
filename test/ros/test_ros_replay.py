"""Replay of twin logs.

Republishing with timing, re-simulation on the recorded commands, and the rerun view. Real rclpy
over FastDDS, real MCAP files, the real rerun loader.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest
from conftest import REPO, ros_environment, session_domain_id

DOMAIN_ID = session_domain_id('replay')             # apart from the node tests' domain
WAIT_S = 300.0          # deadline of a wait (a loaded 2-core machine is slow; nothing is timed)


@pytest.fixture(scope='module')
def ros(tmp_path_factory):
    """Give an rclpy context isolated on its own domain, localhost only."""
    with ros_environment(tmp_path_factory.mktemp('ros'), DOMAIN_ID):
        import rclpy

        rclpy.init()
        yield rclpy
        rclpy.try_shutdown()


def _spin_until(executor, condition, timeout_s):
    deadline = time.monotonic() + timeout_s
    while not condition() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    return condition()


@pytest.fixture(scope='module')
def twin_log(ros, tmp_path_factory):
    """Run a fast twin with commands sent over DDS mid-run, its log split every 2 s.

    Returns the log (the bag directory).
    """
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import Float64
    from threadpoolctl import threadpool_limits

    from drill_twin import interface as itf
    from drill_twin.recording.qos import rclpy_qos_profile
    from drill_twin.ros.parameters import TwinParameters
    from drill_twin.ros.twin_node import create_twin_node

    folder = tmp_path_factory.mktemp('logs')
    with threadpool_limits(limits=1, user_api='blas'):
        node = create_twin_node(TwinParameters(
            fast=True, log_dir=str(folder), ensemble_members=3, seed=11, duration_s=4.0,
            log_split_s=2.0))
        probe = ros.create_node('probe')
        qos = rclpy_qos_profile(itf.STATE_QOS)
        speed = probe.create_publisher(Float64, itf.CMD_TOP_DRIVE_SPEED, qos)
        hook = probe.create_publisher(Float64, itf.CMD_HOOK_LOAD, qos)
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        executor.add_node(probe)
        try:
            # Wait for the twin to hear the probe, then command mid-run.
            assert _spin_until(executor, lambda: speed.get_subscription_count() > 0, WAIT_S)
            assert _spin_until(executor, lambda: node.engine.time_s > 1.0, WAIT_S)
            speed.publish(Float64(data=3.0))
            hook.publish(Float64(data=node.engine.hook_load_command - 10e3))
            assert _spin_until(executor, lambda: node.engine.time_s > 2.0, WAIT_S)
            speed.publish(Float64(data=6.0))
            assert _spin_until(executor, lambda: node.done.done(), WAIT_S)
        finally:
            node.close()
            executor.shutdown()
            node.destroy_node()
            probe.destroy_node()
    (bag,) = folder.iterdir()
    assert len(list(bag.glob('*.mcap'))) == 3      # 0-2 s, 2-4 s, the last tick at 4 s
    return bag


def test_resimulation_reproduces_the_recorded_run(twin_log):
    from drill_twin.recording.resimulate import resimulate

    calls = []
    result = resimulate(twin_log, progress=lambda done, total: calls.append((done, total)))
    assert result.commands == 3
    assert result.compared == 100                      # 4 s at 25 Hz (log_state_rate_hz)
    # Progress in simulated seconds: from 0 to the whole 4 s, every 1000 steps and at the end.
    assert calls[0] == (0.0, 4.0) and calls[-1] == (4.0, 4.0) and len(calls) == 2
    # mean, lower and upper at 10 Hz (ticks 10, 20, ..., 400, stamped a tick behind): the
    # worker process's ensemble of the node against this process's
    assert result.ensemble_compared == 3 * 40
    assert result.identical, (result.max_difference, result.ensemble_max_difference)


def test_resimulate_command(twin_log):
    result = subprocess.run([sys.executable, '-m', 'drill_twin.cli.main', 'replay',
                             str(twin_log), '--resimulate'], capture_output=True, text=True,
                            cwd=REPO, timeout=WAIT_S)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().endswith('identical')
    assert '100 bit states compared, 3 commands replayed' in result.stdout
    assert '120 ensemble mean and bound states compared' in result.stdout


def test_resimulate_the_first_split_alone(twin_log):
    """One split file is a log too: its 2 s are reproduced from the metadata it carries."""
    from drill_twin.recording.reader import log_files
    from drill_twin.recording.resimulate import resimulate

    first = log_files(twin_log)[0]
    result = resimulate(first)
    assert 47 <= result.compared < 100 and result.identical          # 2 s at 25 Hz


def _altered_log(twin_log, path, config_change=None, seed_change=0):
    """Copy ``twin_log`` to one file whose recorded configuration or seed is altered."""
    import dataclasses

    import yaml

    from drill_twin.recording.log_metadata import RECORD_NAME, TwinLogMetadata
    from drill_twin.recording.mcap_log import McapLog
    from drill_twin.recording.reader import iter_messages, read_metadata
    from drill_twin.recording.topics import twin_topics

    metadata = TwinLogMetadata.from_record(read_metadata(twin_log)[RECORD_NAME])
    config = yaml.safe_load(metadata.config_yaml)
    if config_change:
        config_change(config)
    metadata = dataclasses.replace(metadata, config_yaml=yaml.safe_dump(config),
                                   seed=metadata.seed + seed_change)
    with McapLog(path) as log:
        for topic, spec in twin_topics([700.0, 1590.0]).items():
            log.add_topic(topic, spec.type_name, spec.qos)
        log.add_metadata(RECORD_NAME, metadata.to_record())
        for item in iter_messages(twin_log):
            log.write(item.topic, item.message, item.log_time_ns)
    return path


def test_resimulation_detects_a_different_model(twin_log, tmp_path):
    """A log whose model differs from its recorded configuration is not reproduced."""
    from drill_twin.recording.resimulate import resimulate

    def stiffer_cutting_torque(config):
        config['bit_rock']['a5_n_m'] *= 1.01

    result = resimulate(_altered_log(twin_log, tmp_path / 'altered.mcap',
                                     stiffer_cutting_torque))
    assert not result.identical
    assert result.max_difference['torque_on_bit_nm'] > 1.0


def test_resimulation_detects_a_different_seed(twin_log, tmp_path):
    """Another seed draws other germs: the mean model is reproduced, the ensemble is not."""
    from drill_twin.recording.resimulate import resimulate

    result = resimulate(_altered_log(twin_log, tmp_path / 'reseeded.mcap', seed_change=1))
    assert all(value == 0.0 for value in result.max_difference.values())
    assert not result.identical
    assert result.ensemble_max_difference['torque_on_bit_nm'] > 1.0


def test_replay_republishes_with_the_recorded_values(ros, twin_log):
    """``drill-twin replay`` in another process; a probe here receives the bit states.

    In the log's order and with its values, none lost between the first and the last heard
    (reliable); ``--delay 6`` leaves time for discovery (FastDDS: 1-2 s, longer on a busy
    machine): what is published before it completes is lost, as on a real network.
    """
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import JointState

    from drill_twin import interface as itf
    from drill_twin.recording.qos import rclpy_qos_profile
    from drill_twin.recording.reader import iter_messages

    recorded = {}
    for item in iter_messages(twin_log, topics=[itf.BIT_STATE]):
        stamp = item.message.header.stamp
        recorded[(stamp.sec, stamp.nanosec)] = list(item.message.velocity)
    received = []
    probe = ros.create_node('replay_probe')

    def keep(message):
        received.append(((message.header.stamp.sec, message.header.stamp.nanosec),
                         list(message.velocity)))

    probe.create_subscription(JointState, itf.BIT_STATE, keep, rclpy_qos_profile(itf.STATE_QOS))
    executor = SingleThreadedExecutor()
    executor.add_node(probe)
    env = dict(os.environ)
    process = subprocess.Popen([sys.executable, '-m', 'drill_twin.cli.main', 'replay',
                                str(twin_log), '--rate', '1.0', '--delay', '6'], env=env,
                               cwd=REPO,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + WAIT_S
        while process.poll() is None and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        last = sorted(recorded)[-1]
        _spin_until(executor, lambda: received and received[-1][0] == last, 10.0)
        out, err = process.communicate(timeout=WAIT_S)
    finally:
        if process.poll() is None:
            process.kill()
        executor.shutdown()
        probe.destroy_node()
    assert process.returncode == 0, err
    assert 'replayed' in out
    stamps, ordered = [stamp for stamp, _ in received], sorted(recorded)
    assert len(stamps) > 0.5 * len(recorded)
    first = ordered.index(stamps[0])
    assert stamps == ordered[first:first + len(stamps)]       # in order, none lost between
    for stamp, velocity in received:
        assert velocity == recorded[stamp]


def test_view_writes_an_rrd_with_the_twin_entities(twin_log, tmp_path, ros):
    out = tmp_path / 'run.rrd'
    result = subprocess.run([sys.executable, '-m', 'drill_twin.cli.main', 'view', str(twin_log),
                             '--rrd', str(out)], capture_output=True, text=True, cwd=REPO,
                            timeout=WAIT_S, env=dict(os.environ))
    assert result.returncode == 0, result.stderr
    assert out.stat().st_size > 0
    rerun = os.path.join(os.path.dirname(sys.executable), 'rerun')
    listing = subprocess.run([rerun, 'rrd', 'print', str(out)], capture_output=True, text=True,
                             timeout=120, env=dict(os.environ))
    text = listing.stdout + listing.stderr
    for entity in ('/bit/speed', '/ensemble/speed/band', '/lateral/x700m/orbit'):
        assert entity in text, entity


def test_replay_errors(tmp_path, capsys):
    missing = subprocess.run([sys.executable, '-m', 'drill_twin.cli.main', 'replay',
                              str(tmp_path / 'none.mcap')], capture_output=True, text=True,
                             cwd=REPO, timeout=60)
    assert missing.returncode == 2
    assert missing.stderr.strip() == f'drill-twin: {tmp_path / "none.mcap"}: no such file'
    from drill_twin.cli.main import main

    empty = tmp_path / 'empty_dir'
    empty.mkdir()
    for command in (['replay', str(empty), '--resimulate'], ['view', str(empty)]):
        assert main(command) == 2
        assert capsys.readouterr().err.splitlines() == [
            f'drill-twin: {empty}: no MCAP files in it (not a log)']
