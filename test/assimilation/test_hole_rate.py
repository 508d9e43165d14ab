"""
The hole's rate windows (assimilation/hole_rate.py).

The block's slope against each member's own drilling. The bookkeeping is checked on batches
whose holes and blocks the tests move by hand (a member's hole advancing at a known rate,
jumps between steps as an analysis makes them, a linear analysis applied to every member's
state), against closed forms and numpy's least-squares fit; the filter's use of it on the
real model in the last test.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from drill_twin.assimilation.hole_rate import HoleRateWindows
from drill_twin.assimilation.sequential import Sample, SequentialFilter
from drill_twin.assimilation.settings import load_assimilation
from drill_twin.config import load_config
from drill_twin.integrator.simulator import Simulator
from drill_twin.uncertainty.germ import germs_for_realizations

DT = 0.01
RATES = np.array([1.0e-4, 2.0e-4, 3.0e-4])            # m/s, each member's law
STRETCH = np.array([0.5, 0.6, 0.7])                    # m, block above the hole bottom
BLOCK_STD = 0.002                                      # m
NONE = np.zeros(3)                                     # bit speeds and WOB (unused here)


class _Holes:
    """The hole bottoms of a batch (m), as ``Simulator.hole_u`` gives them."""

    def __init__(self, holes):
        self.holes = np.array(holes, dtype=float)

    def hole_u(self):
        return self.holes


def _drill(batch, windows, start_s, end_s, rates, stretch):
    """Step from start_s to end_s: the holes advance at ``rates``; return the last time."""
    time = start_s
    for _ in range(int(round((end_s - start_s) / DT))):
        time += DT
        batch.holes = batch.holes + rates * DT
        windows.after_step(time, batch.holes + stretch, NONE, NONE)
    return time


def _block_samples(windows, window_s, slope):
    """Offer 10 Hz block samples of a line of ``slope`` with a zigzag; return them."""
    stamps = np.arange(1, int(round(window_s * 10)) + 1) / 10.0
    values = 0.02 + slope * stamps + 0.001 * (-1.0) ** np.arange(stamps.size)
    for stamp, value in zip(stamps, values):
        windows.offer(stamp, value)
    return stamps, values


def test_a_members_slope_is_what_its_law_drilled_not_what_an_analysis_moved():
    """
    Jumps of the hole between steps (an analysis moving an on-bottom bit) are not drilling.

    The own slope is each member's rate to rounding, where the slope of its block is off by the
    jump; the block's slope and its variance are numpy's least-squares fit's.
    """
    batch = _Holes([10.0, 10.0, 10.0])
    windows = HoleRateWindows(batch, 3, 10.0, 0.0)
    stamps, values = _block_samples(windows, 10.0, 1.5e-4)
    blocks = []
    time = 0.0
    for _ in range(1000):
        time += DT
        if abs(time - 4.0) < DT / 2:                  # the analysis: bit and hole jump together
            batch.holes = batch.holes + np.array([0.01, -0.005, 0.02])
            windows.after_write()
        batch.holes = batch.holes + RATES * DT
        blocks.append(batch.holes + STRETCH)
        windows.after_step(time, blocks[-1], NONE, NONE)
    assert windows.due(time, lambda value: BLOCK_STD) == []        # not over yet
    time = _drill(batch, windows, time, time + DT, RATES, STRETCH)
    [observation] = windows.due(time, lambda value: BLOCK_STD)
    np.testing.assert_allclose(observation.predicted, RATES, rtol=1e-9)
    times = DT * np.arange(1, 1001)
    block_slopes = np.polyfit(times, np.array(blocks), 1)[0]
    assert np.all(np.abs(block_slopes - RATES) > 2 * RATES.max())   # what the jump would do
    slope, covariance = np.polyfit(stamps, values, 1, cov='unscaled')
    assert observation.observed_m_per_s == pytest.approx(slope[0], rel=1e-9)
    assert observation.variance == pytest.approx(BLOCK_STD ** 2 * covariance[0, 0], rel=1e-9)
    assert observation.samples == stamps.size


def test_a_linear_analysis_acts_on_the_window_as_on_the_members_histories():
    """
    The smoother step: after a transform T of every member's state, the slopes are T @ rates.

    For linear dynamics the analysed members' histories are T times the forecast ones, so
    their slopes over the whole window are T times the forecast slopes.
    """
    rng = np.random.default_rng(3)
    matrix = np.eye(3) + 0.3 * rng.standard_normal((3, 3))
    batch = _Holes([10.0, 11.0, 12.0])
    windows = HoleRateWindows(batch, 3, 10.0, 0.0)
    _block_samples(windows, 10.0, 1.5e-4)
    time = _drill(batch, windows, 0.0, 5.0, RATES, STRETCH)
    batch.holes = matrix @ batch.holes                # the members, hole, rate and stretch
    rates, stretch = matrix @ RATES, matrix @ STRETCH
    windows.transform(matrix)
    windows.after_write()
    time = _drill(batch, windows, time, 10.01, rates, stretch)
    [observation] = windows.due(time, lambda value: BLOCK_STD)
    np.testing.assert_allclose(observation.predicted, matrix @ RATES, rtol=0, atol=1e-12)


def test_a_copied_member_takes_its_sources_history():
    batch = _Holes([10.0, 10.0, 10.0])
    windows = HoleRateWindows(batch, 3, 10.0, 0.0)
    _block_samples(windows, 10.0, 1.5e-4)
    time = _drill(batch, windows, 0.0, 3.0, RATES, STRETCH)
    batch.holes[0] = batch.holes[2]                   # member 0 becomes a copy of member 2
    windows.copy([0], [2])
    stretch = STRETCH.copy()
    stretch[0] = stretch[2]
    rates = RATES.copy()
    rates[0] = rates[2]
    time = _drill(batch, windows, time, 10.01, rates, stretch)
    [observation] = windows.due(time, lambda value: BLOCK_STD)
    np.testing.assert_allclose(observation.predicted, RATES[[2, 1, 2]], rtol=1e-9)


def test_a_window_waits_for_its_late_samples_and_needs_half_of_them():
    """Analysed after its end plus the hook's delay; samples over less than half: skipped."""
    batch = _Holes([10.0, 10.0, 10.0])
    windows = HoleRateWindows(batch, 3, 10.0, 0.0, delay_s=2.0)
    for stamp in np.arange(1, 41) / 10.0:             # only the first 4 s of the window
        windows.offer(stamp, 0.02 + 1e-4 * stamp)
    for stamp in np.arange(101, 201) / 10.0:          # all of the second
        windows.offer(stamp, 0.02 + 2e-4 * stamp)
    time = _drill(batch, windows, 0.0, 11.0, RATES, STRETCH)
    assert windows.due(time, lambda value: BLOCK_STD) == []        # the delay is not over
    time = _drill(batch, windows, time, 12.0, RATES, STRETCH)
    assert windows.due(time, lambda value: BLOCK_STD) == []        # 4 s of 10: skipped
    windows.offer(5.0, 1.0)                           # stamped in a window already analysed
    time = _drill(batch, windows, time, 22.0, RATES, STRETCH)
    [observation] = windows.due(time, lambda value: BLOCK_STD)
    assert (observation.start_s, observation.end_s) == (10.0, 20.0)
    assert observation.observed_m_per_s == pytest.approx(2e-4, rel=1e-9)
    np.testing.assert_allclose(observation.predicted, RATES, rtol=1e-9)


SMALL = ['sections.drill_pipe.elements=8', 'sections.drill_collar.elements=4',
         'reduced_basis.lateral_modes=6']


@pytest.fixture(scope='module')
def config():
    return load_config(None, SMALL)


def _window_filter(config, window_s, prediction='own_drilling'):
    settings = load_assimilation(None, [
        'assimilation.filter.members=6', 'assimilation.filter.parameters=law',
        'assimilation.filter.model_error_bit_speed_rad_per_s=0.0',
        'assimilation.filter.measurements=[block_position]',
        'assimilation.filter.analysis_rate_hz=5.0',
        f'assimilation.filter.hole_rate_window_s={window_s!r}',
        f'assimilation.filter.hole_rate_prediction={prediction}'])
    simulator = Simulator(config, 6, germs=germs_for_realizations(0.2, 0, range(6)),
                          law_scales=np.exp(0.3 * np.random.default_rng(1).standard_normal(
                              (6, 5))))
    return simulator, SequentialFilter(simulator, 6, settings, np.random.default_rng(0))


def test_the_filter_adds_the_window_to_the_analysis_that_closes_it(config):
    """
    The analysis after the window's end holds one more measurement: the block's slope.

    Block samples equal to the members' mean prediction at 10 Hz; the record carries their
    least-squares slope and the members' mean own slope, NaN in the other analyses.
    """
    simulator, sequential = _window_filter(config, 0.5)
    dt = simulator.dt
    stamps, values, records = [], [], []
    for step in range(1, int(round(0.8 / dt)) + 1):
        simulator.step()
        record = sequential.after_step()
        if step % int(round(0.1 / dt)) == 0:
            stamp = simulator.time_s
            value = float(sequential._prediction_at(stamp)[:, 0].mean())
            stamps.append(stamp)
            values.append(value)
            sequential.offer(Sample('hook', stamp, {'block_position': value}))
        if record is not None:
            records.append(record)
    closing = [r for r in records if math.isfinite(r.hole_rate_observed_m_per_s)]
    assert len(closing) == 1 and closing[0].time_s == pytest.approx(0.6)
    assert closing[0].measurements == 3               # the samples at 0.5 and 0.6 s, the slope
    inside = np.array(stamps) <= 0.5 + 1e-9
    slope = np.polyfit(np.array(stamps)[inside], np.array(values)[inside], 1)[0]
    assert closing[0].hole_rate_observed_m_per_s == pytest.approx(slope, rel=1e-9)
    assert math.isfinite(closing[0].hole_rate_predicted_m_per_s)
    assert all(math.isnan(r.hole_rate_observed_m_per_s) for r in records if r is not closing[0])


def test_the_steady_law_prediction_is_each_members_law_balancing_its_mean_weight(config):
    """
    With ``steady_law``, a member predicts the ROP at which its law balances its mean WOB.

    Over a 0.5 s window of the real model (6 members, their own germs and factors of a1 ...
    a5, on bottom): each prediction is a ROP at which the member's random law, at the bit
    speed the test averaged over the window's steps, pushes back exactly the WOB averaged
    likewise (BitRockLaw.forces, F1 = -WOB), and it differs from the member's own drilling.
    """
    simulator, sequential = _window_filter(config, 0.5, 'steady_law')
    windows = sequential.hole_rate
    speeds, weights = [], []
    while simulator.time_s < 0.5 - 1e-9:
        simulator.step()
        sequential._record()
        speeds.append(simulator.last.bit_speed_rad_per_s[:6].copy())
        weights.append(-simulator.last.weight_on_bit_n[:6].copy())
    simulator.step()
    sequential._record()                                   # closes the window
    window = windows._closed[0]
    predicted = windows.steady_rates(window)
    speed, weight = np.mean(speeds, axis=0), np.mean(weights, axis=0)
    assert np.all(weight > 0) and np.all(predicted > 0)
    law, scales = simulator.law, simulator.integrator.law_scales
    for i in range(6):
        force, _, lifted = law.scaled(scales[i]).forces(
            np.array([predicted[i]]), np.array([speed[i]]), simulator.integrator.germ[i:i + 1])
        assert not lifted[0]
        assert -force[0] == pytest.approx(weight[i], rel=1e-9)
    assert not np.allclose(predicted, window.member_slopes(), rtol=0.1)
