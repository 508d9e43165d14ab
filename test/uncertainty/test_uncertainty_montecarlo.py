"""Monte Carlo studies: the mean-model limit, envelopes, Eq. 54 and reproducibility."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import REPO

from drill_twin.config import load_config
from drill_twin.config.loader import config_to_dict
from drill_twin.uncertainty.executors import (DaskExecutor, LocalProcessExecutor,
                                              SerialExecutor)
from drill_twin.uncertainty.montecarlo import (LARGEST_BATCH, MEAN_MODEL_GERM, QUANTITIES,
                                               StudySpec, default_batch_size, run_chunk)
from drill_twin.uncertainty.study import run_study


def _spec(**changes):
    values = dict(dispersion=0.01, samples=5, duration_s=2.0, seed=3, window_s=1.5,
                  batch_size=2, station_m=700.0)
    values.update(changes)
    return StudySpec(**values)


@pytest.fixture(scope='module')
def config():
    return load_config()


@pytest.fixture(scope='module')
def serial_study(config):
    return run_study(config, _spec(), SerialExecutor())


@pytest.fixture(scope='module')
def one_worker_study(config):
    executor = LocalProcessExecutor(1)
    try:
        return run_study(config, _spec(), executor)
    finally:
        executor.close()


def test_vanishing_dispersion_reproduces_the_mean_model(config):
    result = run_study(config, _spec(dispersion=0.0, samples=2), SerialExecutor())
    for q in QUANTITIES:
        np.testing.assert_allclose(result.realizations[q], result.mean_model[q][None].repeat(2, 0),
                                   rtol=1e-12, atol=1e-15)
    small = run_study(config, _spec(dispersion=1e-6, samples=2), SerialExecutor())
    rop = small.realizations['rop_m_per_s']
    assert np.abs(rop - small.mean_model['rop_m_per_s']).max() < 1e-4 * np.abs(rop).max()
    assert np.abs(rop - small.mean_model['rop_m_per_s']).max() > 0


def test_the_identity_germ_is_the_mean_law(config):
    """
    The study integrates its mean model as a batch member with [G] = I.

    That must be the mean law exactly, lift-off and Jacobian included, on and off the admissible
    set.
    """
    from drill_twin.model.bit_rock import BitRockLaw

    law = BitRockLaw.from_config(config.bit_rock)
    rng = np.random.default_rng(1)
    rop = np.concatenate([rng.uniform(-0.01, 0.02, 500), [0.0, 1e-12, 2.6e-3]])
    omega = np.concatenate([rng.uniform(-2.0, 12.0, 500), [5.2, 1e-12, 0.0]])
    germ = np.repeat(MEAN_MODEL_GERM[None], rop.size, axis=0)
    for mean, identity in zip(law.forces_and_jacobian(rop, omega),
                              law.forces_and_jacobian(rop, omega, germ)):
        np.testing.assert_array_equal(identity, mean)
    for mean, identity in zip(law.forces(rop, omega), law.forces(rop, omega, germ)):
        np.testing.assert_array_equal(identity, mean)


def test_the_mean_model_rides_with_the_first_chunk(config, serial_study):
    """
    The study's mean model is the mean law's run, and it leaves the realizations alone.

    The mean model is the mean law's run (to the rounding of its batch), and the first chunk's
    realizations are those of a chunk without it (to rounding).
    """
    spec = _spec()
    alone = run_chunk(json.dumps(config_to_dict(config)), spec, (0,), mean_model=False)
    plain = run_chunk(json.dumps(config_to_dict(config)), spec, (), mean_model=True)
    assert plain.indices.size == 0 and plain.mean_model is not None
    for q in QUANTITIES:
        scale = np.abs(plain.mean_model[q]).max()
        np.testing.assert_allclose(serial_study.mean_model[q], plain.mean_model[q], rtol=0,
                                   atol=1e-12 * scale)
        np.testing.assert_allclose(serial_study.realizations[q][0], alone.series[q][0],
                                   rtol=0, atol=1e-12 * np.abs(alone.series[q]).max())
    assert not np.allclose(serial_study.realizations['rop_m_per_s'][0],
                           serial_study.mean_model['rop_m_per_s'])


@pytest.mark.parametrize('samples', [1, 5, 32, 63, 64, 65, 150, 1000])
@pytest.mark.parametrize('workers', [1, 2, 3, 8])
def test_default_batches_share_the_work_evenly(samples, workers):
    batch = default_batch_size(samples, workers)
    sizes = [len(c) for c in StudySpec(dispersion=0.01, samples=samples, duration_s=1.0, seed=0,
                                       window_s=1.0, batch_size=batch,
                                       station_m=700.0).chunks()]
    assert sum(sizes) == samples and max(sizes) <= LARGEST_BATCH
    assert max(sizes) - min(sizes) < len(sizes)               # equal but for a remainder
    if samples >= 2 * workers:
        assert len(sizes) % workers == 0                     # every worker gets as many


def test_envelopes_contain_the_stochastic_mean(serial_study):
    for q, envelope in serial_study.envelopes().items():
        assert np.all(envelope.lower <= envelope.mean + 1e-12), q
        assert np.all(envelope.mean <= envelope.upper + 1e-12), q
        assert np.any(envelope.upper - envelope.lower > 0), q
    frequency, spectra = serial_study.spectra()
    for q, (_, envelope) in spectra.items():
        assert np.all(envelope.lower <= envelope.mean + 1e-15)
        assert np.all(envelope.mean <= envelope.upper + 1e-15)


def test_dispersion_widens_the_response(config):
    spreads = []
    for delta in (0.001, 0.01, 0.1):
        result = run_study(config, _spec(dispersion=delta, samples=6, duration_s=4.0,
                                         window_s=2.0, batch_size=6), SerialExecutor())
        spreads.append(result.coefficient_of_variation()['rop'])
    assert spreads[0] < spreads[1] < spreads[2]


def test_same_seed_same_results_whatever_the_workers(config, one_worker_study, serial_study):
    executor = LocalProcessExecutor(2)
    try:
        parallel = run_study(config, _spec(), executor)
    finally:
        executor.close()
    for q in QUANTITIES:
        np.testing.assert_array_equal(parallel.realizations[q], one_worker_study.realizations[q])
        scale = np.abs(serial_study.realizations[q]).max()
        np.testing.assert_allclose(serial_study.realizations[q], parallel.realizations[q],
                                   rtol=0, atol=1e-12 * scale)       # in-process: rounding
    np.testing.assert_array_equal(parallel.norm_integral, one_worker_study.norm_integral)


def test_same_results_on_a_dask_cluster(config, one_worker_study):
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        executor = DaskExecutor(cluster.scheduler_address)
        try:
            distributed = run_study(config, _spec(), executor)
        finally:
            executor.close()
    for q in QUANTITIES:
        np.testing.assert_array_equal(distributed.realizations[q],
                                      one_worker_study.realizations[q])


def test_a_realization_depends_on_its_index_not_on_the_study(config, serial_study):
    """
    Realization j draws its germ from the stream (seed, j).

    A larger study starts the same, a batch of another size changes it only by rounding, another
    seed changes it.
    """
    larger = run_study(config, _spec(samples=7), SerialExecutor())
    for q in QUANTITIES:
        np.testing.assert_array_equal(larger.realizations[q][:4], serial_study.realizations[q][:4])
    rebatched = run_study(config, _spec(batch_size=5), SerialExecutor())
    for q in QUANTITIES:
        scale = np.abs(serial_study.realizations[q]).max()
        np.testing.assert_allclose(rebatched.realizations[q], serial_study.realizations[q],
                                   rtol=0, atol=1e-9 * scale)
    other = run_study(config, _spec(seed=4), SerialExecutor())
    assert not np.allclose(other.realizations['rop_m_per_s'],
                           serial_study.realizations['rop_m_per_s'])


def test_mean_square_convergence_of_a_spinning_string():
    """
    Eq. 54 with U the driven rotation alone.

    int sum_nodes (Omega t)^2 dt = n_nodes Omega^2 T^3 / 3
    (bit-rock law off, no lateral deflection, and no mass-proportional damping, whose drag on
    the spinning string would twist it by 0.06 rad in 2 s).
    """
    config = load_config(None, ['physics.bit_rock=false', 'damping.mass_coefficient_per_s=0',
                                'initial_conditions.lateral_deflection_m=0'])
    duration = 2.0
    result = run_study(config, _spec(samples=3, duration_s=duration, window_s=1.0),
                       SerialExecutor())
    omega = config.operation.top_drive_speed_rad_per_s
    nodes = sum(s.elements for s in config.sections) + 1
    expected = nodes * omega ** 2 * duration ** 3 / 3
    np.testing.assert_allclose(result.norm_integral, expected, rtol=1e-4)
    conv = result.convergence()
    np.testing.assert_allclose(conv, np.cumsum(result.norm_integral) / np.arange(1, 4))


def test_montecarlo_command(tmp_path):
    out = tmp_path / 'study'
    result = subprocess.run(
        [sys.executable, '-m', 'drill_twin.cli.main', 'montecarlo', '--delta', '0.01',
         '--samples', '4', '--duration', '2', '--window', '1', '--batch-size', '2',
         '--workers', '1', '--seed', '7', '--out', str(out)],
        capture_output=True, text=True, cwd=REPO, timeout=600)
    assert result.returncode == 0, result.stderr
    summary = json.loads((out / 'summary.json').read_text())
    assert (summary['samples'], summary['delta'], summary['seed']) == (4, 0.01, 7)
    assert set(summary['coefficient_of_variation']) == {'rop', 'weight_on_bit',
                                                        'torque_on_bit', 'bit_speed'}
    for key in ('realizations_with_impacts', 'realizations_with_lift_off'):
        assert isinstance(summary[key], int)
    statistics = np.load(out / 'statistics.npz')
    for q in QUANTITIES:
        for suffix in ('mean_model', 'mean', 'lower', 'upper', 'spectrum_mean_model',
                       'spectrum_mean', 'spectrum_lower', 'spectrum_upper'):
            assert f'{q}__{suffix}' in statistics.files
    assert statistics['conv'].shape == (4,)
    assert load_config(out / 'config.yaml') == load_config()      # the study can be re-run
    for name in ('fig07_convergence.png', 'fig08_rop.png', 'fig10_bit_speed.png',
                 'fig11_radial_displacement.png', 'fig16_rop_realizations.png'):
        assert (out / name).read_bytes()[:4] == b'\x89PNG'


@pytest.mark.parametrize('args, message', [
    (('--delta', '0.9', '--samples', '2'), 'dispersion'),
    (('--delta', '0.01', '--samples', '2', '--station', '650'),
     '--station: 650.0 m is not one of'),
    (('--delta', '0.01', '--samples', '0'), 'samples: must be at least 1'),
    (('--delta', '0.01', '--samples', '2', '--workers', '0'), '--workers: must lie in 1 ... '),
])
def test_montecarlo_bad_arguments(tmp_path, args, message):
    result = subprocess.run([sys.executable, '-m', 'drill_twin.cli.main', 'montecarlo', *args,
                             '--duration', '1', '--out', str(tmp_path / 'x')],
                            capture_output=True, text=True, cwd=REPO, timeout=120)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], result.stderr
