"""
Start-up of ``drill-twin twin``.

Node parameters checked before the node starts (one line, exit 2, whether given as options,
``-p`` rules or in a params file), rclpy's own refusal caught as a backstop, and SIGINT/SIGTERM
honoured from the first instant.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from cli_output import assert_one_line
from conftest import ros_variables, session_domain_id

from drill_twin.ros.parameters import (ParameterError, check_parameter, model_overrides,
                                       parameters_from_ros_arguments, validate_ros_arguments)

DOMAIN_ID = session_domain_id('command line')       # apart from the node tests' domain


@pytest.fixture
def env(tmp_path):
    return dict(os.environ, **ros_variables(tmp_path, DOMAIN_ID))


def run_twin(*args, env, cwd):
    return subprocess.run([sys.executable, '-m', 'drill_twin.cli.main', 'twin', '--no-log',
                           '--duration', '1', *args], capture_output=True, text=True,
                          env=env, cwd=cwd, timeout=300, stdin=subprocess.DEVNULL)


# -- parameters, through the command -----------------------------------------------------------

@pytest.mark.parametrize('args, words', [
    (('--ensemble', '-3'), '--ensemble: must lie in 0 ... 256, got -3 (parameter '
                           'ensemble_members)'),
    (('--delta', '5'), '--delta: must lie in 0 ... 0.65, got 5'),
    (('--ros-args', '-p', 'rate_hz:=0'), '--ros-args -p: rate_hz: must lie in 1 ... 1000, got 0'),
    ('file', 'params.yaml: rate_hz: must lie in 1 ... 1000, got 0'),
    ('unknown', 'params.yaml: colour: unknown parameter of the twin node'),
    (('--assimilation', 'no-such.yaml'), '--assimilation: no-such.yaml: no such file'),
    (('--assimilate', '--ensemble', '1'), 'ensemble_members: assimilation needs at least 2 '
                                          'ensemble members, got 1'),
    (('--assimilate', '--ros-args', '-p',
      'assimilation_overrides:=["assimilation.filter.inflation=0.5"]'),
     'inflation: must be >= 1'),
    (('--ros-args', '--bogus'), "drill-twin: ROS arguments: unknown ['--bogus']"),
], ids=['ensemble', 'delta', '-p', 'params-file', 'unknown', 'assimilation-file',
        'assimilation-members', 'assimilation-override', 'unknown-ros-argument'])
def test_out_of_range_node_parameters_are_one_line(tmp_path, env, args, words):
    if isinstance(args, str):
        path = tmp_path / 'params.yaml'
        line = '    rate_hz: 0.0\n' if args == 'file' else '    colour: red\n'
        path.write_text('/**:\n  ros__parameters:\n' + line)
        args = ('--params-file', str(path))
    assert_one_line(run_twin(*args, env=env, cwd=tmp_path), words)


def test_rclpy_refusing_a_parameter_is_one_line_too(tmp_path, env):
    """
    The node run directly (as a program embedding it would), past the command line's checks.

    Rclpy's InvalidParameterValueException becomes one line and status 2.
    """
    code = ('import sys\n'
            'from drill_twin.ros.twin_node import run\n'
            'sys.exit(run(["drill-twin", "--ros-args", "-p", "log_enabled:=false", "-p", '
            '"ensemble_members:=-3"]))\n')
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            env=env, cwd=tmp_path, timeout=300)
    assert_one_line(result, 'drill-twin: parameter: ', 'ensemble_members')


# -- parameters, the rules (no process) --------------------------------------------------------

def test_a_params_file_applies_to_the_node_by_name_namespace_or_wildcard(tmp_path):
    path = tmp_path / 'params.yaml'
    path.write_text('other_node:\n  ros__parameters:\n    rate_hz: 0.0\n'
                    '/rig/drill_twin:\n  ros__parameters:\n    seed: 4\n'
                    '/**:\n  ros__parameters:\n    kpi_rate_hz: 5.0\n')
    values = validate_ros_arguments(['--ros-args', '--params-file', str(path), '-p',
                                     'seed:=7', '-p', 'other_node:rate_hz:=0.0'])
    assert values['seed'] == 7 and values['kpi_rate_hz'] == 5.0 and values['rate_hz'] == 100.0
    assert parameters_from_ros_arguments(['--ros-args', '-r', '__ns:=/rig', '-p',
                                          'fast:=true']) == [('--ros-args -p', 'fast', True)]


@pytest.mark.parametrize('name, value, words', [
    ('rate_hz', 200, 'write 200.0'),               # rclpy takes no integer for a double
    ('duration_s', 'inf', 'must be finite'),
    ('fast', 'yes please', 'expected true or false'),
    ('on_log_error', 'panic', 'must be one of continue, exit'),
    ('model_overrides', 'a=1', 'expected a list of strings'),
])
def test_parameter_types_and_ranges_follow_rclpy(name, value, words):
    with pytest.raises(ParameterError, match=words):
        check_parameter(name, value)


def test_the_hook_load_limits_must_be_ordered():
    with pytest.raises(ParameterError, match='hook_load_min_n: 6e\\+06 exceeds hook_load_max_n'):
        validate_ros_arguments(['-p', 'hook_load_min_n:=6.0e6'])


def test_the_model_overrides_of_the_node():
    values = validate_ros_arguments(['-p', 'time_step_s:=0.02', '-p', 'model_overrides:=["a=1"]'])
    assert model_overrides(values) == ['integration.time_step_s=0.02', 'a=1']
    values = validate_ros_arguments(['-p', 'top_drive_controller:=impedance', '-p',
                                     'model_overrides:=["a=1"]'])
    assert model_overrides(values) == ['integration.time_step_s=0.005',
                                       'top_drive.controller=impedance', 'a=1']


# -- signals at start-up ------------------------------------------------------------------------

def _signal_mask(pid: int, field: str) -> int:
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith(field + ':'):
            return int(line.split()[1], 16)
    raise AssertionError(field)


@pytest.mark.skipif(not Path('/proc/self/status').exists(), reason='needs /proc (Linux)')
@pytest.mark.parametrize('number', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_a_stop_signal_during_start_up_stops_the_twin_cleanly(tmp_path, number):
    """
    A stop signal during start-up stops the twin at once, with status 0.

    Started as a non-interactive shell starts a background job (SIGINT ignored), the twin
    catches SIGINT and SIGTERM before it has even loaded rclpy, and a signal then (0.1 s
    after the start at the earliest) stops it at once with status 0 and no traceback.
    """
    env = dict(os.environ, **ros_variables(tmp_path, DOMAIN_ID))

    def as_background_job():
        signal.signal(signal.SIGINT, signal.SIG_IGN)

    start = time.monotonic()
    process = subprocess.Popen(
        [sys.executable, '-m', 'drill_twin.cli.main', 'twin', '--no-log', '--duration', '600'],
        preexec_fn=as_background_job, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL, text=True, env=env, cwd=tmp_path)
    try:
        bit = 1 << (number - 1)
        while not _signal_mask(process.pid, 'SigCgt') & bit:
            assert process.poll() is None and time.monotonic() - start < 300
            time.sleep(0.001)
        loaded = Path(f'/proc/{process.pid}/maps').read_text()
        time.sleep(max(0.0, 0.1 - (time.monotonic() - start)))
        process.send_signal(number)
        _, stderr = process.communicate(timeout=300)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert 'rclpy' not in loaded, 'the stop signals were caught only once rclpy was loaded'
    assert process.returncode == 0, stderr
    assert 'Traceback' not in stderr and 'ensemble members' not in stderr, stderr


def test_the_twin_keeps_discovery_on_its_host_unless_told():
    """ROS_AUTOMATIC_DISCOVERY_RANGE: LOCALHOST by default; a range already set is kept."""
    from drill_twin.cli.twin import close_discovery

    environ = {}
    assert close_discovery(environ) == 'LOCALHOST'
    assert environ == {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}
    opened = {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET'}
    assert close_discovery(opened) == 'SUBNET'
    assert opened == {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET'}
