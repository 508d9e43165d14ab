"""drill-twin map: the stick-slip map, its files, and its agreement with linear stability."""
from __future__ import annotations

import csv
import json
import pickle

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drill_twin.cli.common import UsageError
from drill_twin.cli.main import main
from drill_twin.cli.map import parse_values
from drill_twin.config import load_config
from drill_twin.config.checks import ConfigValueError
from drill_twin.config.loader import config_to_dict
from drill_twin.simulation.stick_slip_map import (COLUMNS, SSI_STEADY, MapPointError, MapSpec,
                                                  compare_with_linear_stability,
                                                  oscillation_frequency, run_map, run_point)
from drill_twin.simulation.stick_slip_map_io import read_map, write_map
from drill_twin.uncertainty.executors import LocalProcessExecutor, SerialExecutor
from drill_twin.viz.map_figure import plot_map

# A coarse string whose axial-torsional motion is linear but for the bit-rock law (seconds
# per point); lateral motion, contact and finite strain are off.
COARSE = ['reduced_basis.lateral_modes=0', 'reduced_basis.torsional_modes=2',
          'reduced_basis.axial_modes=1', 'sections.drill_pipe.elements=8',
          'sections.drill_collar.elements=4', 'physics.contact=false',
          'physics.finite_strain=false', 'physics.kinetic_coupling=false',
          'integration.time_step_s=0.02']
CONTRACT = ('top_drive_speed_rad_per_s', 'weight_on_bit_n', 'weight_on_bit_mean_n',
            'stick_slip_severity', 'bit_speed_min_rad_per_s', 'bit_speed_mean_rad_per_s',
            'backward_rotation', 'lift_off_count', 'impact_count', 'rop_m_per_s', 'mse_pa',
            'growth_rate_per_s', 'frequency_hz', 'linearly_stable', 'failed', 'error')


def _set_options(overrides):
    return [item for value in overrides for item in ('--set', value)]


@pytest.fixture(scope='module')
def coarse_map():
    """
    Run 3 x 3 points across the linear boundary, 24 s each.

    Stable at 3 rad/s and at 50 kN, unstable at 9-15 rad/s with 130-200 kN; each from steady
    drilling kicked by 0.5 rad/s.
    """
    config = load_config(None, COARSE)
    spec = MapSpec(speeds_rad_per_s=(3.0, 9.0, 15.0), weights_on_bit_n=(50e3, 130e3, 200e3),
                   duration_s=24.0, window_s=14.0)
    return run_map(config, spec, SerialExecutor())


def test_simulated_points_agree_with_the_linear_stability(coarse_map):
    """
    Linearly stable points are steady (SSI < 0.05), unstable ones oscillate.

    But within one grid step of the boundary; away from it both classes are represented.
    """
    verdicts = [row['linear_comparison'] for row in coarse_map.rows]
    assert 'disagree' not in verdicts and 'failed' not in verdicts
    agreeing = [row for row in coarse_map.rows if row['linear_comparison'] == 'agree']
    assert {row['linearly_stable'] for row in agreeing} == {0, 1}
    # Here even the points next to the boundary agree (none is within a few % of it):
    for row in coarse_map.rows:
        steady = row['stick_slip_severity'] < SSI_STEADY
        assert steady == bool(row['linearly_stable']), row


def test_the_limit_cycle_runs_at_the_first_torsional_mode(coarse_map):
    """
    Unstable points oscillate near the frequency of the growing eigenvalue.

    That of the first torsional mode, lowered by the stick phases as the severity grows.
    """
    for row in coarse_map.rows:
        if not row['linearly_stable']:
            assert 0.6 * row['frequency_hz'] < row['oscillation_frequency_hz'] \
                < 1.1 * row['frequency_hz'], row


def test_the_weight_on_bit_is_set_through_the_hook_load(coarse_map):
    """
    Momentum balance of the axially free string.

    The mean WOB is W - H whatever the stick-slip (to the drag and the change of axial momentum
    over the window).
    """
    wob = coarse_map.column('weight_on_bit_n')
    assert_allclose(coarse_map.column('weight_on_bit_mean_n'), wob, rtol=2e-3)
    weight = coarse_map.column('hook_load_n') + wob
    assert_allclose(weight, weight[0, 0], rtol=1e-12)          # W = H + WOB, one string


def test_steady_points_drill_at_the_laws_steady_rate(coarse_map):
    """
    ROP is the rate the hole deepens; where drilling is steady it is the law's steady ROP.

    At the linearly stable points that stay steady (SSI < 0.05) the hole deepens at the ROP of
    Eq. 25 at (Omega, WOB) within 1 %, or not at all where that ROP is negative (below the
    cutting threshold the rock holds the bit), and where it deepens MSE is Teale's with that
    ROP, the law's TOB and the top speed (the bit turns at it when steady) within 1 %.
    """
    steady = ((coarse_map.column('linearly_stable') == 1)
              & (coarse_map.column('stick_slip_severity') < 0.05))
    rop = coarse_map.column('rop_m_per_s')[steady]
    law = coarse_map.column('steady_rop_m_per_s')[steady]
    assert (law > 0).sum() >= 3 and (law < 0).sum() >= 1           # 3 rad/s and 50 kN: < 0
    assert_allclose(rop, np.maximum(law, 0.0), rtol=0.01, atol=1e-9)
    cutting = law > 0
    area = np.pi * load_config(None, COARSE).borehole.diameter_m ** 2 / 4
    speed = coarse_map.column('top_drive_speed_rad_per_s')[steady][cutting]
    expected = (coarse_map.column('weight_on_bit_n')[steady][cutting] / area
                + np.abs(coarse_map.column('steady_torque_on_bit_nm')[steady][cutting]) * speed
                / (area * rop[cutting]))
    assert_allclose(coarse_map.column('mse_pa')[steady][cutting], expected, rtol=0.01)


def test_backward_rotation_is_flagged_from_the_bit_speed(coarse_map):
    backward = coarse_map.column('backward_rotation') == 1
    assert_allclose(backward, coarse_map.column('bit_speed_min_rad_per_s') < 0)
    assert np.any(backward)                               # 200 kN at 9 and 15 rad/s


def test_comparison_exempts_points_one_grid_step_from_the_boundary():
    stable = np.array([[1, 1, 1], [1, 0, 0], [1, 0, 0]], dtype=bool)
    severity = np.where(stable, 0.01, 0.8)
    severity[0, 0] = 0.3                                 # a stable point that oscillates
    failed = np.zeros_like(stable)
    failed[2, 2] = True
    verdict = compare_with_linear_stability(severity, stable, failed)
    assert verdict[0, 0] == 'disagree'
    assert verdict[1, 1] == 'near_boundary' and verdict[0, 1] == 'near_boundary'
    assert verdict[2, 2] == 'failed'
    assert verdict[0, 2] == 'near_boundary' and verdict[2, 0] == 'near_boundary'


def test_oscillation_frequency_of_a_sinusoid():
    dt = 0.01
    t = dt * np.arange(2000)
    assert oscillation_frequency(3 + np.sin(2 * np.pi * 0.21 * t + 0.4), dt) == \
        pytest.approx(0.21, rel=1e-4)
    assert np.isnan(oscillation_frequency(np.ones(100), dt))


@pytest.mark.parametrize('text, expected', [
    ('2:20:10', np.linspace(2, 20, 10)), ('5,10,15', [5, 10, 15]),
    ('20,2:8:4', [2, 4, 6, 8, 20]), ('50e3:250e3:5', [50e3, 100e3, 150e3, 200e3, 250e3])])
def test_values_accept_lists_and_ranges(text, expected):
    assert_allclose(parse_values('--speeds', text), expected)


@pytest.mark.parametrize('text', ['2:20', 'fast', '2:20:1', '5,5', '1:2:x', 'nan'])
def test_malformed_values_are_refused(text):
    with pytest.raises(UsageError, match='--speeds'):
        parse_values('--speeds', text)


@pytest.mark.parametrize('options, option', [
    (['--speeds', '2:x:3', '--weights-on-bit', '1e5'], '--speeds'),
    (['--speeds', '5', '--weights-on-bit', '-100000'], '--weights-on-bit'),
    (['--speeds', '-5', '--weights-on-bit', '1e5'], '--speeds'),
    (['--speeds', '5', '--weights-on-bit', '1e5', '--window', '30'], '--window'),
    (['--speeds', '5', '--weights-on-bit', '1e5', '--workers', '0'], '--workers'),
    (['--speeds', '5', '--weights-on-bit', '1e5', '--perturbation', '-1'], '--perturbation'),
    (['--speeds', '5', '--weights-on-bit', '1e5', '--set', 'integration.time_step_s=-1'],
     'time_step_s'),
    # A point the configuration refuses is refused before any point runs (it broke the pool).
    (['--speeds', '2,1000', '--weights-on-bit', '1e5'],
     '--speeds: 1000 rad/s: operation.top_drive_speed_hz: must be at most 10'),
    (['--speeds', '5', '--weights-on-bit', '1e5,5e6'],
     '--weights-on-bit: 5e+06 N (hook load -3.837e+06 N): operation.hook_load_n: must be >= 0'),
    # A still bit has no steady drilling (the linearisation gave a growth rate of +28 631 /s).
    (['--speeds', '0,5', '--weights-on-bit', '1e5'],
     '--speeds: must be > 0 (at 0 the bit does not turn'),
    (['--speeds', '5', '--weights-on-bit', '1e5', '--set', 'reduced_basis.lateral_modes=10000'],
     'the model cannot be built from it: reduced_basis.lateral_modes: asked for 10000')])
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, options, option):
    code = main(['map', '--duration', '10', '--out', str(tmp_path / 'map')] + options)
    error = capsys.readouterr().err
    assert code == 2
    assert error.count('\n') == 1 and error.startswith('drill-twin: ') and option in error
    assert not (tmp_path / 'map').exists()


def test_a_point_refused_in_a_worker_comes_back_as_its_error():
    """
    A configuration error raised in a worker process reaches the parent intact.

    Run directly (run_map checks the grid first), a point at 1000 rad/s fails its
    configuration's check in the worker; the error crosses back by pickling, and the pool
    keeps working.
    """
    config_json = json.dumps(config_to_dict(load_config(None, COARSE)))
    spec = MapSpec(speeds_rad_per_s=(1000.0,), weights_on_bit_n=(1e5,), duration_s=1.0,
                   window_s=1.0)
    executor = LocalProcessExecutor(1)
    try:
        with pytest.raises(ConfigValueError) as info:
            list(executor.run(run_point, [(config_json, spec, 0)]))
        assert info.value.key == 'operation.top_drive_speed_hz'
        assert 'must be at most 10' in info.value.message
        with pytest.raises(ConfigValueError):                  # the pool still runs tasks
            list(executor.run(run_point, [(config_json, spec, 0)]))
    finally:
        executor.close()


def test_grid_errors_survive_pickling():
    error = MapPointError('speeds_rad_per_s', '1000 rad/s: too fast')
    again = pickle.loads(pickle.dumps(error))
    assert (type(again), str(again), again.key) == (MapPointError, str(error), error.key)


def test_cli_writes_the_map_and_a_process_pool_reproduces_an_in_process_run(tmp_path):
    """
    The command's files and columns (the contract).

    The same numbers from a worker process as from this process with the written config.yaml.
    """
    out = tmp_path / 'map'
    options = ['--speeds', '4,8', '--weights-on-bit', '150e3', '--duration', '2',
               '--window', '1', '--seed', '7']
    assert main(['map', '--workers', '1', '--out', str(out)] + options
                + _set_options(COARSE)) == 0
    for name in ('map.csv', 'map.png', 'config.yaml', 'map.json', 'linear_stability.csv'):
        assert (out / name).is_file(), name
    with open(out / 'map.csv', newline='') as stream:
        rows = list(csv.DictReader(stream))
    assert list(rows[0]) == list(COLUMNS)
    assert set(CONTRACT) <= set(rows[0])
    assert [float(r['top_drive_speed_rad_per_s']) for r in rows] == [4.0, 8.0]
    assert float(rows[1]['top_drive_speed_rpm']) == pytest.approx(8.0 * 60 / (2 * np.pi))
    assert json.loads((out / 'map.json').read_text())['seed'] == 7

    # config.yaml repeats the map: in this process, from that file alone.
    spec = MapSpec(speeds_rad_per_s=(4.0, 8.0), weights_on_bit_n=(150e3,), duration_s=2.0,
                   window_s=1.0, seed=7)
    write_map(run_map(load_config(out / 'config.yaml'), spec, SerialExecutor()),
              tmp_path / 'serial')
    reference = _numbers(out / 'map.csv')
    assert _numbers(tmp_path / 'serial' / 'map.csv') == reference


def _numbers(path):
    with open(path, newline='') as stream:
        return [{k: v for k, v in row.items() if k != 'wall_time_s'}
                for row in csv.DictReader(stream)]


def test_a_diverging_point_is_a_failed_row_not_a_crash(tmp_path):
    """
    A point whose step cannot converge is written as failed; the others still run.

    One iteration allowed, an unreachable tolerance: the point is written as NaN statistics
    with failed = 1 and the error.
    """
    config = load_config(None, COARSE + ['integration.max_iterations=1',
                                         'integration.tolerance=1e-300'])
    spec = MapSpec(speeds_rad_per_s=(8.0,), weights_on_bit_n=(150e3,), duration_s=1.0,
                   window_s=0.5)
    result = run_map(config, spec, SerialExecutor())
    row = result.rows[0]
    assert row['failed'] == 1 and row['error'] and np.isnan(row['stick_slip_severity'])
    assert np.isfinite(row['growth_rate_per_s'])          # the linear part still holds
    write_map(result, tmp_path)
    plot_map(result, tmp_path / 'map.png')
    with open(tmp_path / 'map.csv', newline='') as stream:
        written = next(csv.DictReader(stream))
    assert written['failed'] == '1' and written['stick_slip_severity'] == 'nan'
    assert json.loads((tmp_path / 'map.json').read_text())['failed_points']
    again = read_map(tmp_path)
    assert again.spec == spec and again.failed_points()[0]['error'] == row['error']
    assert_allclose(again.boundary_growth_rate_per_s, result.boundary_growth_rate_per_s,
                    rtol=1e-8)


def test_docs_list_every_column():
    from conftest import REPO

    from drill_twin.simulation.stick_slip_map_io import markdown_table
    text = (REPO / 'docs' / 'MAP.md').read_text()
    assert markdown_table() in text, 'regenerate the table with markdown_table()'
