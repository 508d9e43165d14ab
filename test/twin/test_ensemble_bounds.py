"""
The ensemble's published bounds against numpy's and scipy's, from the members' raw values.

A snapshot's ensemble_lower and ensemble_upper are the 2.5 % and 97.5 % levels of the members'
bit state: numpy.quantile (linear interpolation) in open loop; with an ensemble filter, as its
``filter.bounds`` says, the Student-t prediction interval mean -+ t_{0.975, N-1} s
sqrt(1 + 1/N) or numpy's quantiles. The expected values are computed here from the members'
states read off the ensemble's simulator, never from the engine's own statistics.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import stats
from threadpoolctl import threadpool_limits

from drill_twin.assimilation.settings import load_assimilation
from drill_twin.config import load_config
from drill_twin.twin.engine import BitState, EnsembleSettings, TwinEngine

SMALL = ['sections.drill_pipe.elements=8', 'sections.drill_collar.elements=4',
         'reduced_basis.lateral_modes=6', 'integration.time_step_s=0.01']
FIELDS = tuple(f.name for f in dataclasses.fields(BitState))


@pytest.fixture(scope='module')
def config():
    return load_config(None, SMALL)


def _members(engine) -> dict[str, np.ndarray]:
    """Return the members' bit state now, {field: (N,)}, read off the ensemble's simulator."""
    observed = engine.ensemble_runner.simulator.observe(detailed=0)
    return {name: np.array(getattr(observed, name), dtype=float) for name in FIELDS}


def _published(snapshot) -> dict[str, tuple[float, float, float]]:
    """Return {field: (mean, lower, upper)} of a snapshot."""
    return {name: (getattr(snapshot.ensemble_mean, name), getattr(snapshot.ensemble_lower, name),
                   getattr(snapshot.ensemble_upper, name)) for name in FIELDS}


def _run(engine, ticks: int):
    """Advance ``ticks`` one-step ticks; yield each snapshot with the members' values then."""
    with threadpool_limits(limits=1, user_api='blas'):
        for _ in range(ticks):
            snapshot = engine.advance(1)
            yield snapshot, _members(engine)


def _assert_close(published: float, expected: float, scale: float) -> None:
    assert published == pytest.approx(expected, rel=1e-12, abs=1e-12 * scale)


def test_open_loop_bounds_are_numpys_2_5_and_97_5_percent_quantiles(config):
    """
    Nine members in open loop: the bounds are numpy.quantile's at 0.025 and 0.975.

    With N = 9 the levels fall between order statistics (0.2 and 7.8 of 0..8), so a level
    or an interpolation of the wrong kind moves them. The mean is the members' mean.
    """
    engine = TwinEngine(config, EnsembleSettings(members=9, dispersion=0.3, seed=5))
    try:
        checked = 0
        for snapshot, members in _run(engine, 60):
            assert snapshot.ensemble_step == engine.ensemble_runner.step_index
            for name, (mean, lower, upper) in _published(snapshot).items():
                values = members[name]
                scale = float(np.max(np.abs(values)))
                low, high = np.quantile(values, [0.025, 0.975])
                _assert_close(mean, float(np.mean(values)), scale)
                _assert_close(lower, float(low), scale)
                _assert_close(upper, float(high), scale)
                checked += np.ptp(values) > 0
    finally:
        engine.close()
    assert checked > 60 * 3                    # the members differ: the levels are tested


@pytest.mark.parametrize('method', ['student_t', 'percentile'])
def test_the_filters_bounds_are_the_student_t_interval_or_numpys_quantiles(config, method):
    """
    With an ensemble filter of five members, the bounds its ``filter.bounds`` names.

    student_t: mean -+ t s sqrt(1 + 1/N), t = scipy.stats.t.ppf(0.975, N - 1) (2.776 for
    N = 5), s the members' sample standard deviation (ddof 1); percentile: numpy.quantile's
    2.5 % and 97.5 % of the members.
    """
    settings = load_assimilation(None, [
        'assimilation.filter.members=5', f'assimilation.filter.bounds={method}',
        'assimilation.filter.measurements=[top_torque]'])
    n = 5
    engine = TwinEngine(config, EnsembleSettings(members=n, dispersion=0.3, seed=2,
                                                 assimilation=settings))
    t = stats.t.ppf(0.975, n - 1)
    assert t == pytest.approx(2.7764451, rel=1e-7)                 # the tables' t_{0.975, 4}
    try:
        checked = 0
        for snapshot, members in _run(engine, 40):
            for name, (mean, lower, upper) in _published(snapshot).items():
                values = members[name]
                scale = float(np.max(np.abs(values)))
                centre = float(np.mean(values))
                if method == 'student_t':
                    half = t * np.std(values, ddof=1) * np.sqrt(1.0 + 1.0 / n)
                    low, high = centre - half, centre + half
                else:
                    low, high = np.quantile(values, [0.025, 0.975])
                _assert_close(mean, centre, scale)
                _assert_close(lower, float(low), scale)
                _assert_close(upper, float(high), scale)
                checked += np.ptp(values) > 0
    finally:
        engine.close()
    assert checked > 40 * 3
