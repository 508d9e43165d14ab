"""The log fails mid-run for real.

A full disk (a 256 KiB tmpfs mounted for the test, root only) or, everywhere, a file-size limit
(RLIMIT_FSIZE: writes fail with EFBIG). Both ``on_log_error`` policies: ``exit`` stops the twin
with status 1, ``continue`` runs on without a log; either way an ERROR on /rosout and on
/diagnostics says the log stopped, and the bag stays valid: every split it completed (2 s each
on the tmpfs) is listed in its metadata.yaml and whole (rosbags reads them), the cut split is
read to its last chunk (chunks are flushed every second of log time, so the cut split holds one
however fast the twin).

The twin and a probe run in a child process (the limit applies to it alone); the child
prints what the probe heard as JSON.
"""
from __future__ import annotations

import contextlib
import json
import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import REPO, ros_variables, session_domain_id

from drill_twin.recording import reader
from drill_twin.recording.bag import listed_splits

WAIT_S = 300.0
"""Deadline of a child's run (s): a loaded 2-core machine is slow; nothing is timed."""
DISK_BYTES = 256 * 1024
FILE_BYTES = 60_000          # the file-size limit: the first split fails at about 1.3 s
DRILL_TWIN = str(Path(sys.executable).with_name('drill-twin'))

TWIN_AND_PROBE = r'''
import json, sys
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import Log
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from drill_twin.ros.parameters import TwinParameters
from drill_twin.ros.twin_node import create_twin_node

log_dir, policy, split_s = sys.argv[1], sys.argv[2], float(sys.argv[3])
rclpy.init()
node = create_twin_node(TwinParameters(
    fast=True, log_dir=log_dir, on_log_error=policy, log_split_s=split_s,
    ensemble_members=0, duration_s=5.0, log_state_rate_hz=100.0))   # every tick: fills the disk
probe = rclpy.create_node('probe')
heard = {'diagnostics': [], 'rosout': [], 'last_bit_stamp_ns': -1}
deep = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)


def stamp_ns(message):
    return message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec


def on_diagnostics(message):
    for status in message.status:
        heard['diagnostics'].append({'level': int.from_bytes(status.level, 'little'),
                                     'message': status.message, 'stamp_ns': stamp_ns(message),
                                     'values': {kv.key: kv.value for kv in status.values}})


def on_bit_state(message):
    heard['last_bit_stamp_ns'] = max(heard['last_bit_stamp_ns'], stamp_ns(message))


probe.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, deep)
probe.create_subscription(JointState, '/drill_twin/bit/state', on_bit_state, deep)
probe.create_subscription(Log, '/rosout', lambda m: heard['rosout'].append(
    {'level': m.level, 'name': m.name, 'msg': m.msg}), QoSProfile(
        depth=5000, reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL))
executor = SingleThreadedExecutor()
executor.add_node(node)
executor.add_node(probe)
executor.spin_until_future_complete(node.done, timeout_sec=270)
for _ in range(40):                       # what the last tick published
    executor.spin_once(timeout_sec=0.05)
heard.update(done=node.done.done(), result=node.done.result(), failed=node.failed,
             log_error=node.run_log.error, log_is_none=node.log is None)
node.close()
print(json.dumps(heard))
status = 1 if node.failed else 0          # as drill_twin.ros.twin_node.run
executor.shutdown()
node.destroy_node()
probe.destroy_node()
rclpy.try_shutdown()
sys.exit(status)
'''


@pytest.fixture(scope='module')
def env(tmp_path_factory):
    folder = tmp_path_factory.mktemp('log_failure')
    domain = session_domain_id('processes')
    return dict(os.environ, PYTHONPATH=str(REPO), **ros_variables(folder, domain))


@contextlib.contextmanager
def full_disk(medium: str, folder: Path):
    """(log directory, preexec_fn).

    A small tmpfs, or a plain directory and a file-size limit for the child.
    """
    if medium == 'rlimit':
        def limit():
            resource.setrlimit(resource.RLIMIT_FSIZE, (FILE_BYTES, FILE_BYTES))
        yield folder, limit
        return
    folder.mkdir()
    mounted = subprocess.run(['mount', '-t', 'tmpfs', '-o', f'size={DISK_BYTES}', 'tmpfs',
                              str(folder)], capture_output=True, text=True)
    if mounted.returncode != 0:
        pytest.skip(f'cannot mount a tmpfs ({mounted.stderr.strip()}); the rlimit case runs')
    try:
        yield folder, None
    finally:
        subprocess.run(['umount', '-l', str(folder)], check=False)


EXPECTED_ERRNO = {'tmpfs': '[Errno 28] No space left on device',
                  'rlimit': '[Errno 27] File too large'}
SPLIT_S = {'tmpfs': 2.0, 'rlimit': 300.0}     # per-file limit: no split could be completed


def check_bag(log_dir: Path, medium: str) -> None:
    """Check the bag left behind.

    Its metadata.yaml opens in rosbags and lists only whole splits (at least one on the tmpfs);
    the project's reader also reads the cut split's prefix.
    """
    from rosbags.highlevel import AnyReader

    (bag,) = [p for p in log_dir.iterdir() if p.is_dir()]
    listed = listed_splits(bag)
    assert bool(listed) == (medium == 'tmpfs'), listed
    assert all(reader.is_complete(split) for split in listed)
    with AnyReader([bag]) as anyreader:
        count = sum(1 for c, _, raw in anyreader.messages()
                    if anyreader.deserialize(raw, c.msgtype) is not None)
    assert (count > 0) == bool(listed)
    assert len(list(reader.iter_messages(bag))) > count        # and the cut split's prefix


@pytest.mark.parametrize('medium, policy', [('tmpfs', 'exit'), ('tmpfs', 'continue'),
                                            ('rlimit', 'exit')])
def test_log_failure_is_reported_and_obeyed(env, tmp_path, medium, policy):
    """Fail the log mid-run and check what the twin and its bag do.

    (A file-size limit with on_log_error: continue is test_ros_twin_log's
    test_log_write_failure_mid_run.)
    """
    with full_disk(medium, tmp_path / 'disk') as (log_dir, preexec):
        result = subprocess.run([sys.executable, '-c', TWIN_AND_PROBE, str(log_dir), policy,
                                 str(SPLIT_S[medium])],
                                env=env, capture_output=True, text=True, timeout=WAIT_S,
                                stdin=subprocess.DEVNULL, cwd=REPO, preexec_fn=preexec)
        assert result.stdout, result.stderr
        heard = json.loads(result.stdout.splitlines()[-1])
        assert 'Traceback' not in result.stderr
        errno = EXPECTED_ERRNO[medium]
        # the ERROR on /diagnostics, the health status saying the log stopped
        errors = [d for d in heard['diagnostics'] if d['level'] == 2]
        assert len(errors) == 1, heard['diagnostics']
        assert errors[0]['values']['log'] == 'stopped'
        assert errors[0]['message'].startswith('the log stopped: writing the log ')
        assert errno in errors[0]['message']
        # ... and on /rosout
        rosout = [m['msg'] for m in heard['rosout'] if m['name'] == 'drill_twin'
                  and m['level'] == 40]
        assert len(rosout) == 1 and errno in rosout[0]
        assert heard['log_is_none'] and errno in heard['log_error']
        failed_at_ns = errors[0]['stamp_ns']          # the twin time of the failing tick
        if policy == 'exit':                          # stopped at that tick
            assert result.returncode == 1 and heard['failed'] and heard['result'] is False
            assert rosout[0].endswith('; stopping (on_log_error: exit)')
            assert heard['last_bit_stamp_ns'] == failed_at_ns < 5_000_000_000
        else:                                         # ran on to duration_s (5 s)
            assert result.returncode == 0 and not heard['failed'] and heard['result'] is True
            assert rosout[0].endswith('; the twin runs on without a log '
                                      '(on_log_error: continue)')
            assert failed_at_ns < heard['last_bit_stamp_ns'] == 5_000_000_000
        check_bag(log_dir, medium)


def test_cli_exits_with_status_1_when_the_disk_fills(env, tmp_path):
    """``drill-twin twin`` itself: status 1 and the ERROR line, with on_log_error: exit."""
    medium = 'tmpfs' if os.geteuid() == 0 else 'rlimit'
    with full_disk(medium, tmp_path / 'disk') as (log_dir, preexec):
        result = subprocess.run([DRILL_TWIN, 'twin', '--fast', '--duration', '30', '--ensemble',
                                 '0', '--log-dir', str(log_dir), '--ros-args', '-p',
                                 'on_log_error:=exit', '-p', f'log_split_s:={SPLIT_S[medium]}'],
                                env=env, capture_output=True, text=True, timeout=WAIT_S,
                                stdin=subprocess.DEVNULL, cwd=REPO, preexec_fn=preexec)
        assert result.returncode == 1, result.stderr
        assert 'Traceback' not in result.stderr
        errors = [line for line in result.stderr.splitlines() if line.startswith('[ERROR]')]
        assert len(errors) == 1, result.stderr
        assert EXPECTED_ERRNO[medium] in errors[0]
        assert errors[0].endswith('; stopping (on_log_error: exit)')
        assert '30 s simulated' not in result.stderr
        check_bag(log_dir, medium)
