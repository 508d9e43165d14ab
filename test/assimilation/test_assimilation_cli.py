"""drill-twin rig and drill-twin assimilate end to end on a small model, and bad input."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cli_output import assert_one_line
import rerun_capture
from rerun_capture import rrd_chunks
from drill_twin.assimilation.measurements import read
from drill_twin.assimilation.settings import load_assimilation

rerun_env = rerun_capture.rerun_env        # a fixture, requested by name below

ROOT = Path(__file__).resolve().parents[2]
SMALL = ['--set', 'sections.drill_pipe.elements=8', '--set', 'sections.drill_collar.elements=4',
         '--set', 'reduced_basis.lateral_modes=6']
SENSORS = ['--set', 'assimilation.sensors.downhole.rate_hz=8',
           '--set', 'assimilation.sensors.downhole.delay_s=0.25',
           '--set', 'assimilation.filter.analysis_rate_hz=5.0']    # 2 analyses in 0.5 s


def drill_twin(*args, check=False):
    environment = dict(os.environ, PYTHONPATH=str(ROOT))
    result = subprocess.run([sys.executable, '-m', 'drill_twin.cli.main', *args],
                            capture_output=True, text=True, env=environment, timeout=600)
    if check:
        assert result.returncode == 0, result.stderr[-3000:]
    return result


@pytest.fixture(scope='module')
def rig_log(tmp_path_factory):
    path = tmp_path_factory.mktemp('rig') / 'rig.mcap'
    drill_twin('rig', *SMALL, *SENSORS, '--duration', '0.5', '--out', str(path), check=True)
    return path


def test_the_rig_log_holds_measurements_commands_and_truth_only(rig_log):
    from drill_twin.cli.rig_files import read_rig_log
    from drill_twin.recording.reader import topics

    assert set(topics(rig_log)) == {'/rig/top_drive', '/rig/hook', '/rig/downhole',
                                    '/drill_twin/cmd/top_drive_speed',
                                    '/drill_twin/cmd/hook_load', '/rig/truth/bit_state',
                                    '/rig/truth/hole_depth'}
    settings = load_assimilation(None, SENSORS[1::2])
    log = read_rig_log(rig_log, settings)
    assert log.sensors['top_drive'].stamp_s.size == 5
    downhole = log.sensors['downhole']
    np.testing.assert_allclose(downhole.stamp_s, [0.125, 0.25])     # 0.375... arrive later
    np.testing.assert_allclose(downhole.arrival_s - downhole.stamp_s, 0.25)
    np.testing.assert_allclose(log.speed_commands[0], [0.0, 2 * np.pi * 0.83])
    # The downhole bit speed read is the truth's at the stamp, within its noise (5 sd).
    truth = np.interp(downhole.stamp_s, log.truth.time_s, log.truth.bit_speed_rad_per_s)
    spec = settings.channel('bit_speed')
    assert np.all(np.abs(downhole.values['bit_speed'] - truth) < 5 * spec.std(truth))


def test_assimilate_writes_the_estimate_and_the_summary(rig_log, tmp_path):
    from drill_twin.recording.reader import topics

    summary, out = tmp_path / 's.json', tmp_path / 'est.mcap'
    result = drill_twin('assimilate', str(rig_log), *SMALL, *SENSORS, '--members', '2',
                        '--measurements', 'top_torque,block_position,bit_speed',
                        '--set', 'assimilation.filter.model_error_bit_speed_rad_per_s=0.05',
                        '--set', 'assimilation.filter.parameters=germ',
                        '--out', str(out), '--summary', str(summary), '--settle', '0.1',
                        check=True)
    assert 'RMS error' in result.stdout
    scores = json.loads(summary.read_text())
    for key in ('bit_speed_rms_error_rad_per_s', 'open_loop_bit_speed_rms_error_rad_per_s',
                'bit_speed_coverage_95'):
        assert np.isfinite(scores[key]) and scores[key] >= 0
    assert 0 <= scores['bit_speed_coverage_95'] <= 1
    assert scores['analyses'] == 2 and scores['members'] == 2
    written = topics(out)
    for name in ('mean', 'lower', 'upper'):
        assert f'/drill_twin/assimilation/bit_state/{name}' in written
        assert f'/drill_twin/assimilation/germ/{name}' in written
    assert '/diagnostics' in written and '/rig/truth/bit_state' in written
    assert '/drill_twin/assimilation/law/mean' not in written      # the germ only: no law


def test_assimilate_estimates_the_law_when_asked(rig_log, tmp_path):
    """Parameters 'law': the factors of a1 ... a5 in EST.mcap and in the summary."""
    from drill_twin.recording.reader import topics

    summary, out = tmp_path / 's.json', tmp_path / 'est.mcap'
    drill_twin('assimilate', str(rig_log), *SMALL, *SENSORS, '--members', '2',
               '--set', 'assimilation.filter.parameters=law', '--out', str(out),
               '--summary', str(summary), '--settle', '0.1', check=True)
    factors = json.loads(summary.read_text())['law_scales_mean_final']
    assert len(factors) == 5 and all(0.1 <= f <= 10 for f in factors)
    written = topics(out)
    for name in ('mean', 'lower', 'upper'):
        assert f'/drill_twin/assimilation/law/{name}' in written


def test_assimilate_estimates_a_sensor_bias_when_asked(rig_log, tmp_path):
    """With bias_prior_std the bias is in EST.mcap (labelled by channel) and the summary."""
    from mcap_ros2.reader import read_ros2_messages

    summary, out = tmp_path / 's.json', tmp_path / 'est.mcap'
    drill_twin('assimilate', str(rig_log), *SMALL, *SENSORS, '--members', '2',
               '--measurements', 'top_torque,block_position,torque_on_bit',
               '--set', 'assimilation.channels.top_torque.bias_prior_std=100.0',
               '--out', str(out), '--summary', str(summary), '--settle', '0.1', check=True)
    final = json.loads(summary.read_text())['sensor_bias_final']
    assert set(final) == {'top_torque'}
    assert final['top_torque']['lower'] <= final['top_torque']['mean'] \
        <= final['top_torque']['upper']
    read = {}
    for message in read_ros2_messages(str(out), topics=[
            f'/drill_twin/assimilation/bias/{name}' for name in ('mean', 'lower', 'upper')]):
        read[message.channel.topic.rsplit('/', 1)[1]] = message.ros_msg
    assert set(read) == {'mean', 'lower', 'upper'}
    assert read['mean'].layout.dim[0].label == 'top_torque'
    assert read['mean'].data[0] == pytest.approx(final['top_torque']['mean'], rel=1e-12)


def test_the_estimate_opens_in_rerun_with_its_bounds_the_truth_and_the_open_loop(
        rig_log, tmp_path, rerun_env):
    """
    The estimate opens in rerun: ``drill-twin view EST.mcap --rrd`` (the ensemble tab).

    The .rrd (read back by rerun's own CLI) holds the estimated bit speed's mean and band, the
    open loop's mean and bounds and the log's truth, in rpm, on the estimate's run time (the
    truth's first sample at 0.05 s, its 20 Hz), with the ensemble tab first.
    """
    import subprocess as sp

    from drill_twin.viz.rerun_view import rerun_executable
    out, rrd = tmp_path / 'est.mcap', tmp_path / 'est.rrd'
    drill_twin('assimilate', str(rig_log), *SMALL, *SENSORS, '--members', '2',
               '--out', str(out), check=True)
    result = drill_twin('view', str(out), '--rrd', str(rrd), check=True)
    assert str(rrd) in result.stdout
    columns = rrd_chunks(rrd, rerun_env)
    for entity in ('/ensemble/speed/mean', '/ensemble/speed/band', '/ensemble/speed/truth',
                   '/ensemble/speed/open_loop/mean', '/ensemble/speed/open_loop/upper',
                   '/ensemble/germ/g11/mean'):
        assert 'Scalars:scalars' in columns.get(entity, set()), entity
    verbose = sp.run([rerun_executable(), 'rrd', 'print', '-vvv', str(rrd)], env=rerun_env,
                     capture_output=True, text=True, check=True, timeout=60).stdout
    assert 'truth (green), open loop (grey' in verbose
    from drill_twin.viz.run_columns import read_run
    run = read_run([out])
    truth = run.array('truth', 2)
    np.testing.assert_allclose(truth[:3, 0], [0.05, 0.10, 0.15], atol=1e-9)
    estimate = run.array('estimate/mean', 2)
    assert estimate.shape[0] == truth.shape[0] and np.all(np.isfinite(estimate))


@pytest.mark.parametrize('args, words', [
    (['--members', '1'], ['--members', '>= 2']),
    (['--measurements', 'top_torque,colour'], ['--measurements', 'colour']),
    (['--settle', '-1'], ['--settle']),
    (['--set', 'assimilation.filter.inflation=0.5'], ['assimilation.filter.inflation']),
])
def test_assimilate_refuses_bad_input_in_one_line(rig_log, tmp_path, args, words):
    assert_one_line(drill_twin('assimilate', str(rig_log), '--out', str(tmp_path / 'e.mcap'),
                               *args), *words)


def test_assimilate_refuses_a_log_without_measurements(tmp_path):
    from synthetic import write_synthetic_log

    path = tmp_path / 'twin.mcap'
    write_synthetic_log(path, duration_s=0.5)
    assert_one_line(drill_twin('assimilate', str(path), '--out', str(tmp_path / 'e.mcap')),
                    'no measurement topics')
    assert_one_line(drill_twin('assimilate', str(tmp_path / 'missing.mcap'), '--out',
                               str(tmp_path / 'e.mcap')), 'missing.mcap')


def test_rig_refuses_bad_input_in_one_line(tmp_path):
    assert_one_line(drill_twin('rig', '--out', str(tmp_path / 'r.txt')), '--out')
    assert_one_line(drill_twin('rig', '--out', str(tmp_path / 'r.mcap'), '--duration', '0'),
                    '--duration')
    assert_one_line(drill_twin('rig', '--out', str(tmp_path / 'r.mcap'), '--set',
                               'assimilation.sensors.downhole.delay_s=-1'), 'delay_s')


def test_a_reading_has_the_configured_bias_and_noise():
    settings = load_assimilation(None, ['assimilation.channels.top_torque.bias=100',
                                        'assimilation.channels.top_torque.noise_std=30',
                                        'assimilation.channels.top_torque.noise_relative=0.02'])
    value = np.full(20000, 5000.0)
    errors = read(settings, 'top_torque', value, np.random.default_rng(0)) - value
    expected = np.hypot(30.0, 0.02 * 5000.0)
    assert abs(errors.mean() - 100.0) < 5 * expected / np.sqrt(value.size)
    assert abs(errors.std() / expected - 1) < 0.03


def test_a_channel_on_a_float64_topic_reads_and_assimilates_as_in_joint_state(rig_log, tmp_path):
    """
    ``channels.block_position.topic``: the log carries it as std_msgs/Float64 on its own.

    The same log rewritten so: the block position is on /rig/block_position (Float64, read by
    the independent ``mcap_ros2`` decoder) and no longer in the hook's JointState; read back,
    its samples are the JointState's (stamps: received less the hook's delay, 0 here; the
    same values), and the filter's estimate on it is the JointState log's, bit for bit.
    """
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    from drill_twin.assimilation.offline import run_filter
    from drill_twin.cli.rig_files import read_rig_log, write_rig_log
    from drill_twin.config import load_config

    overrides = SENSORS[1::2] + ['assimilation.filter.members=3',
                                 'assimilation.filter.parameters=germ']
    joint = load_assimilation(None, overrides)
    scalar = load_assimilation(None, overrides + [
        'assimilation.channels.block_position.topic=/rig/block_position'])
    log = read_rig_log(rig_log, joint)
    path = tmp_path / 'float64.mcap'
    write_rig_log(path, log, scalar, {'duration_s': repr(log.duration_s)})
    with open(path, 'rb') as stream:
        decoded = {}
        for schema, channel, message, ros in make_reader(
                stream, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            decoded.setdefault(channel.topic, (schema.name, []))[1].append(ros)
    assert decoded['/rig/block_position'][0] == 'std_msgs/msg/Float64'
    hook = log.sensors['hook']
    np.testing.assert_array_equal([m.data for m in decoded['/rig/block_position'][1]],
                                  hook.values['block_position'])
    assert all(np.isnan(m.position[0]) for m in decoded['/rig/hook'][1])
    again = read_rig_log(path, scalar)
    assert 'block_position' not in again.sensors['hook'].values
    np.testing.assert_allclose(again.scalars['block_position'].stamp_s, hook.stamp_s,
                               atol=1e-9)
    np.testing.assert_array_equal(again.scalars['block_position'].values['block_position'],
                                  hook.values['block_position'])
    config = load_config(None, SMALL[1::2])
    estimates = [run_filter(config, settings, read).arrays()
                 for settings, read in ((joint, log), (scalar, again))]
    assert estimates[0]['analysis_time_s'].size >= 2
    for name in ('filtered', 'germ_mean', 'nis', 'measurements'):
        np.testing.assert_array_equal(estimates[0][name], estimates[1][name])
