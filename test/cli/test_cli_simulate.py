"""``drill-twin simulate``: files a user opens directly, and one-line errors."""
from __future__ import annotations

import csv
import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import REPO

SUMMARY_KEYS = {'rop_m_per_s', 'bit_speed_rad_per_s', 'weight_on_bit_n', 'torque_on_bit_nm',
                'stick_slip_severity', 'mse_pa', 'impact_count', 'lift_off_count',
                'impact_rate_per_s', 'lift_off_rate_per_s', 'real_time_factor', 'time_step_s'}


def _run(*args, cwd=REPO):
    return subprocess.run([sys.executable, '-m', 'drill_twin.cli.main', 'simulate', *args],
                          capture_output=True, text=True, cwd=cwd, timeout=300)


@pytest.fixture(scope='module')
def outputs(tmp_path_factory):
    folder = tmp_path_factory.mktemp('simulate')
    result = _run('--duration', '4', '--window', '3', '--out', str(folder / 'run.csv'),
                  '--summary', str(folder / 'summary.json'), '--plot', str(folder / 'run.png'))
    assert result.returncode == 0, result.stderr
    npz = _run('--duration', '1', '--out', str(folder / 'run.npz'))
    assert npz.returncode == 0, npz.stderr
    return folder, result.stdout


def test_csv_history_opens_with_numpy_and_the_csv_module(outputs):
    folder, _ = outputs
    table = np.genfromtxt(folder / 'run.csv', delimiter=',', names=True)
    names = table.dtype.names
    for column in ('time_s', 'bit_depth_m', 'rop_m_per_s', 'bit_angle_rad', 'bit_speed_rad_per_s',
                   'weight_on_bit_n', 'torque_on_bit_nm', 'depth_of_cut_m_per_rad',
                   'top_torque_nm', 'hook_load_n', 'x700m_v_m', 'x700m_radial_m',
                   'x700m_v_acceleration_m_per_s2', 'x1590m_radial_m', 'contact_nodes'):
        assert column in names, column
    assert table['time_s'][0] == 0.0
    assert table['time_s'][-1] == pytest.approx(4.0)
    np.testing.assert_allclose(np.diff(table['time_s']), 0.01, atol=1e-9)
    # The bit depth grows by the integral of the ROP (kinematics of the record).
    depth_gain = table['bit_depth_m'][-1] - table['bit_depth_m'][0]
    assert depth_gain == pytest.approx(np.trapezoid(table['rop_m_per_s'], table['time_s']),
                                       rel=1e-3)
    with open(folder / 'run.csv') as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == table.size
    assert float(rows[10]['weight_on_bit_n']) < 0


def test_csv_history_opens_with_pandas(outputs):
    import pandas

    folder, _ = outputs
    frame = pandas.read_csv(folder / 'run.csv')
    assert frame['time_s'].iloc[-1] == pytest.approx(4.0)
    assert frame['weight_on_bit_n'].mean() == pytest.approx(-1e5, rel=0.01)


def test_npz_holds_named_arrays_and_the_configuration(outputs):
    folder, _ = outputs
    data = np.load(folder / 'run.npz')
    assert data['rop_m_per_s'].shape == data['time_s'].shape
    metadata = json.loads(str(data['metadata']))
    assert metadata['config']['bit_rock']['a2_m_per_n_s'] == 5.672e-8
    assert set(metadata['summary']) >= SUMMARY_KEYS


def test_summary_json(outputs):
    folder, stdout = outputs
    summary = json.loads((folder / 'summary.json').read_text())
    assert set(summary) >= SUMMARY_KEYS
    for key in ('rop_m_per_s', 'bit_speed_rad_per_s', 'weight_on_bit_n', 'torque_on_bit_nm'):
        assert set(summary[key]) == {'mean', 'min', 'max', 'std'}
        assert summary[key]['min'] <= summary[key]['mean'] <= summary[key]['max']
    assert summary['time_step_s'] == 0.005
    assert summary['real_time_factor'] > 0
    assert summary['weight_on_bit_n']['mean'] == pytest.approx(-1e5, rel=0.01)
    assert 'real-time factor' in stdout


def test_plot_is_a_png(outputs):
    folder, _ = outputs
    assert (folder / 'run.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


@pytest.mark.parametrize('args, message', [
    (('--duration', '-1'), '--duration: must be positive'),
    (('--duration', '1', '--out', 'run.txt'), '--out: run.txt: use a .csv or .npz'),
    (('--duration', '1', '--set', 'integration.time_step_s=-1'),
     '--set: integration.time_step_s: must be a finite positive number'),
])
def test_bad_arguments_give_one_line_and_status_2(args, message, tmp_path):
    result = _run(*args, cwd=tmp_path)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f'drill-twin: {message}'), result.stderr
