"""``drill-twin twin`` and the ``ros2 run`` launcher as processes.

Exit statuses, error lines, and the log they leave, a rosbag2 bag (complete after duration_s,
SIGTERM and SIGINT; read by the project's reader and by rosbags).

Each process runs on a random ROS domain, localhost only, with its ROS and rerun files in a
temporary directory. Waits are loops on conditions with generous deadlines.
"""
from __future__ import annotations

import os
import re
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import REPO, ros_variables, session_domain_id

from drill_twin import interface as itf
from drill_twin.recording import reader
from drill_twin.ros.parameters import BY_NAME

WAIT_S = 300.0
"""Deadline of a wait (s): a run on a loaded 2-core machine may compile the kernels first."""
STATE_PERIOD_NS = round(1e9 / BY_NAME['log_state_rate_hz'].default)
"""The log's every-tick states are the first tick of each period of this length."""
DRILL_TWIN = str(Path(sys.executable).with_name('drill-twin'))


@pytest.fixture(scope='module')
def env(tmp_path_factory):
    folder = tmp_path_factory.mktemp('ros_processes')
    return dict(os.environ, **ros_variables(folder, session_domain_id('processes')))


def run(command: list[str], env: dict, timeout_s: float = WAIT_S) -> subprocess.CompletedProcess:
    return subprocess.run(command, env=env, capture_output=True, text=True, timeout=timeout_s,
                          stdin=subprocess.DEVNULL, cwd=REPO)


def the_log(folder: Path) -> Path:
    """Return the one bag directory in ``folder``."""
    logs = list(folder.iterdir())
    assert len(logs) == 1 and logs[0].is_dir(), logs
    assert re.fullmatch(r'drill_twin_\d{8}T\d{6}Z', logs[0].name), logs[0].name
    return logs[0]


def rosbags_count(path: Path, topic: str) -> int:
    """Messages of ``topic`` in the bag, read and deserialised by rosbags."""
    from rosbags.highlevel import AnyReader

    with AnyReader([path]) as bag:
        connections = [c for c in bag.connections if c.topic == topic]
        return sum(1 for c, _, raw in bag.messages(connections=connections)
                   if bag.deserialize(raw, c.msgtype) is not None)


def bit_stamps(path: Path) -> list[int]:
    return [m.message.header.stamp.sec * 1_000_000_000 + m.message.header.stamp.nanosec
            for m in reader.iter_messages(path, [itf.BIT_STATE], strict=True)]


def bit_stamps_readable(path: Path) -> list[int]:
    """Bit-state stamps of the readable part of a log cut short."""
    return [m.message.header.stamp.sec * 1_000_000_000 + m.message.header.stamp.nanosec
            for m in reader.iter_messages(path, [itf.BIT_STATE])]


def assert_complete_fast_run(path: Path, duration_s: float) -> None:
    """Check a complete, readable log of a fast run: the twin clock from 0 to duration_s.

    The bit states are published every 10 ms tick and logged at log_state_rate_hz (25 Hz);
    the KPIs every 100 ms as published; /clock is not logged (the log time is the clock).
    """
    assert reader.is_complete(path)
    stamps = bit_stamps(path)
    assert stamps == list(range(STATE_PERIOD_NS, int(duration_s * 1e9) + 1, STATE_PERIOD_NS))
    kpi = [m.log_time_ns for m in reader.iter_messages(path, [itf.KPI_ROP], strict=True)]
    assert kpi == list(range(100_000_000, int(duration_s * 1e9) + 1, 100_000_000))
    assert not list(reader.iter_messages(path, [itf.CLOCK]))
    rosout = [m.message.msg for m in reader.iter_messages(path, [itf.ROSOUT], strict=True)]
    assert rosout[-1] == f'{duration_s:g} s simulated: stopping'
    metadata = reader.read_metadata(path)['drill_twin']
    assert metadata['fast'] == 'true' and 'config' in metadata
    assert rosbags_count(path, itf.BIT_STATE) == len(stamps)


# -- 10. the command line -------------------------------------------------------------------

@pytest.mark.parametrize('in_process', [False, True], ids=['worker', 'in_process'])
def test_cli_fast_run_leaves_a_log(env, tmp_path, in_process):
    result = run([DRILL_TWIN, 'twin', '--duration', '1', '--fast', '--ensemble', '2',
                  '--seed', '4', '--log-dir', str(tmp_path / 'logs')]
                 + (['--ensemble-in-process'] if in_process else []), env)
    assert result.returncode == 0, result.stderr
    assert 'Traceback' not in result.stderr
    path = the_log(tmp_path / 'logs')
    assert_complete_fast_run(path, 1.0)
    metadata = reader.read_metadata(path)['drill_twin']
    assert metadata['seed'] == '4' and metadata['ensemble_members'] == '2'
    assert metadata['ensemble_process'] == str(not in_process).lower()
    assert len(list(reader.iter_messages(path, [itf.ENSEMBLE_MEAN]))) == 10


def test_cli_bad_override_is_one_line_and_status_2(env, tmp_path):
    result = run([DRILL_TWIN, 'twin', '--duration', '1', '--fast', '--set', 'foo=1',
                  '--log-dir', str(tmp_path / 'logs')], env)
    assert result.returncode == 2
    assert result.stderr.splitlines() == ['drill-twin: --set: foo: unknown key']
    assert not (tmp_path / 'logs').exists()


# -- 9. unwritable log directory (exit) ------------------------------------------------------

def test_unwritable_log_dir_with_on_log_error_exit(env, tmp_path):
    """A directory under a regular file cannot be created, not even by root."""
    blocker = tmp_path / 'a_file'
    blocker.write_text('not a directory\n')
    result = run([DRILL_TWIN, 'twin', '--duration', '1', '--fast', '--ensemble', '0',
                  '--log-dir', str(blocker / 'logs'), '--ros-args', '-p',
                  'on_log_error:=exit'], env)
    assert result.returncode == 1
    lines = result.stderr.splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith(f'drill-twin: cannot write the log {blocker}/logs/drill_twin_')
    assert lines[0].endswith(': Not a directory (on_log_error: exit)')


def test_log_write_failure_mid_run(env, tmp_path):
    """The log hits the file-size limit (as a full disk would) after ~0.7 s.

    With on_log_error: continue the twin runs to the end, says so once as an ERROR through its
    ROS logger (so on /rosout), and leaves its bag readable. (Python ignores SIGXFSZ, so the
    write raises EFBIG.) test_ros_log_failure checks /diagnostics and on_log_error: exit.
    """
    limit = 40_000                  # zstd chunks: about 45 kB a second of twin time

    def limit_file_size():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    logs = tmp_path / 'logs'
    # Health at 10 Hz of wall time flushes a chunk every 0.1 s, so complete chunks precede the
    # limit however fast the twin runs (at 1 Hz a fast twin's first chunk alone passes 40 kB).
    result = subprocess.run([DRILL_TWIN, 'twin', '--duration', '2', '--fast', '--ensemble', '2',
                             '--log-dir', str(logs), '--ros-args', '-p', 'health_rate_hz:=10.0'],
                            env=env, capture_output=True, text=True,
                            timeout=WAIT_S, stdin=subprocess.DEVNULL, cwd=REPO,
                            preexec_fn=limit_file_size)
    assert result.returncode == 0, result.stderr
    errors = [line for line in result.stderr.splitlines() if line.startswith('[ERROR]')]
    assert len(errors) == 1, result.stderr
    assert re.fullmatch(r'\[ERROR\] \[[0-9.]+\] \[drill_twin\]: writing the log \S+_0\.mcap '
                        r'failed \(\[Errno 27\] File too large\); the twin runs on without a '
                        r'log \(on_log_error: continue\)', errors[0]), errors[0]
    assert result.stderr.splitlines()[-1].endswith('2 s simulated: stopping')
    path = the_log(logs)
    split = path / f'{path.name}_0.mcap'
    assert split.stat().st_size <= limit and not reader.is_complete(path)
    assert len(bit_stamps_readable(path)) > 0


# -- 8. ros2 run launcher, signals -----------------------------------------------------------

def test_ros2_run_launcher(env, tmp_path):
    """``ros2 run drill_twin twin`` runs <prefix>/lib/drill_twin/twin, i.e. scripts/twin."""
    launcher = REPO / 'scripts' / 'twin'
    assert os.access(launcher, os.X_OK)
    logs = tmp_path / 'logs'
    result = run([sys.executable, str(launcher), '--ros-args', '-p', 'duration_s:=1.0',
                  '-p', 'fast:=true', '-p', f'log_dir:={logs}', '-p', 'ensemble_members:=2'],
                 env)
    assert result.returncode == 0, result.stderr
    assert_complete_fast_run(the_log(logs), 1.0)


def _readable_messages(folder: Path) -> int:
    """Bit-state messages readable so far from the (unfinished) log in ``folder``."""
    logs = list(folder.glob('*/*.mcap'))
    if not logs:
        return 0
    return sum(1 for _ in reader.iter_messages(logs[0].parent, [itf.BIT_STATE]))


def _group_alive(group: int) -> bool:
    try:
        os.killpg(group, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.mark.parametrize('signal_number, to_group', [
    (signal.SIGTERM, False), (signal.SIGINT, False), (signal.SIGINT, True)],
    ids=['SIGTERM', 'SIGINT', 'SIGINT-to-the-process-group'])
def test_signal_completes_the_log(env, tmp_path, signal_number, to_group):
    """Real time (100 Hz), stopped by a signal once its log holds messages.

    Exit status 0, no traceback, and a complete log stamped with the ROS time of the run. A
    Ctrl-C in a terminal signals the whole process group, the ensemble worker too: it leaves the
    stopping to the node, and no process of the group outlives the node.
    """
    logs = tmp_path / 'logs'
    stderr_path = tmp_path / 'stderr.txt'
    started_ns = time.time_ns()
    with open(stderr_path, 'w') as stderr:
        process = subprocess.Popen([DRILL_TWIN, 'twin', '--ensemble', '2', '--log-dir',
                                    str(logs)], env=env, cwd=REPO, stdin=subprocess.DEVNULL,
                                   stdout=subprocess.DEVNULL, stderr=stderr,
                                   start_new_session=True)
    try:
        deadline = time.monotonic() + WAIT_S
        while (seen := _readable_messages(logs)) == 0:
            assert process.poll() is None, stderr_path.read_text()
            assert time.monotonic() < deadline, 'no messages in the log'
            time.sleep(0.2)
        if to_group:
            os.killpg(process.pid, signal_number)
        else:
            process.send_signal(signal_number)
        status = process.wait(timeout=WAIT_S)
        deadline = time.monotonic() + 60.0
        while _group_alive(process.pid):
            assert time.monotonic() < deadline, 'a process of the twin outlived it'
            time.sleep(0.05)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        if _group_alive(process.pid):
            os.killpg(process.pid, signal.SIGKILL)
    stopped_ns = time.time_ns()
    errors = stderr_path.read_text()
    assert status == 0, errors
    assert 'Traceback' not in errors and 'Error' not in errors
    path = the_log(logs)
    assert reader.is_complete(path)
    stamps = bit_stamps(path)
    assert len(stamps) >= seen
    # The log holds the first tick's bit state in each 40 ms period (log_state_rate_hz 25):
    # ticks are 10 ms apart, 20 ms when one catches up after a stall of the machine.
    periods = [stamp // STATE_PERIOD_NS for stamp in stamps]
    assert all(b > a for a, b in zip(periods, periods[1:]))
    assert all(0 < b - a <= 2 * STATE_PERIOD_NS for a, b in zip(stamps, stamps[1:]))
    assert started_ns < stamps[0] and stamps[-1] < stopped_ns    # the ROS clock, real time
    assert reader.read_metadata(path)['drill_twin']['fast'] == 'false'
    topics = reader.topics(path)
    assert {itf.BIT_STATE, itf.ENSEMBLE_MEAN, itf.DIAGNOSTICS, itf.ROSOUT} <= set(topics)
    assert rosbags_count(path, itf.BIT_STATE) == len(stamps)


SIGNAL_WHILE_STARTING = '''
import os, signal, sys, time
import rclpy
from drill_twin.ros import build, twin_node

where, name, log_dir = sys.argv[1:4]


def interrupted(function):
    """``function``, after a real signal to this process has shut rclpy's context down."""
    def wrapper(*args, **kwargs):
        os.kill(os.getpid(), getattr(signal, name))
        deadline = time.monotonic() + 60
        while rclpy.ok() and time.monotonic() < deadline:
            time.sleep(0.01)
        return function(*args, **kwargs)
    return wrapper


if where == 'model':            # before anything of ROS is made but the node itself
    build.load_config = interrupted(build.load_config)
else:                           # after the log is opened
    twin_node.TwinNode.create_timer = interrupted(twin_node.TwinNode.create_timer)
sys.exit(twin_node.run(['drill-twin', '--ros-args', '-p', f'log_dir:={log_dir}',
                        '-p', 'ensemble_members:=1']))
'''


@pytest.mark.parametrize('where', ['model', 'timer'])
@pytest.mark.parametrize('name', ['SIGTERM', 'SIGINT'])
def test_signal_while_starting(env, tmp_path, where, name):
    """A signal between rclpy.init and the first spin stops the twin cleanly.

    The moment is chosen by wrapping one call of the node's set-up: exit status 0, no
    traceback, no unfinished log.
    """
    script = tmp_path / 'signal_while_starting.py'
    script.write_text(SIGNAL_WHILE_STARTING)
    logs = tmp_path / 'logs'
    result = run([sys.executable, str(script), where, name, str(logs)], env)
    assert result.returncode == 0, result.stderr
    assert 'Traceback' not in result.stderr
    for path in logs.glob('*'):
        assert reader.is_complete(path)
    assert (where == 'timer') == logs.is_dir()
