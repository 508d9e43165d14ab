"""The twin's ensemble filter: the engine takes rig samples as they arrive.

The same :class:`~drill_twin.assimilation.sequential.SequentialFilter` runs offline over a log
and in the twin's ensemble; these tests check that the twin, fed a rig's samples at their
arrival times, analyses exactly what the offline filter does (in this process and in the
worker process), that late and delayed samples are compared with the predictions at their
stamps, and that bad samples are refused with a reason while the twin goes on.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from drill_twin.assimilation.offline import run_filter
from drill_twin.assimilation.rig_emulator import run_rig
from drill_twin.assimilation.sequential import Sample, SequentialFilter
from drill_twin.assimilation.settings import load_assimilation
from drill_twin.config import load_config
from drill_twin.integrator.simulator import Simulator
from drill_twin.twin.engine import EnsembleSettings, TwinEngine
from drill_twin.uncertainty.germ import germs_for_realizations

SMALL = ['sections.drill_pipe.elements=8', 'sections.drill_collar.elements=4',
         'reduced_basis.lateral_modes=6']
DURATION_S = 2.0


@pytest.fixture(scope='module')
def config():
    return load_config(None, SMALL)


@pytest.fixture(scope='module')
def settings():
    """
    Surface torque and block position at 10 Hz, bit speed by mud pulse 0.5 s late at 2 Hz.

    Analysed at 5 Hz: ten analyses in the 2 s log.
    """
    return load_assimilation(None, [
        'assimilation.filter.members=4', 'assimilation.filter.analysis_rate_hz=5.0',
        'assimilation.filter.measurements=[top_torque,block_position,bit_speed]',
        'assimilation.sensors.downhole.rate_hz=2.0',
        'assimilation.sensors.downhole.delay_s=0.5'])


@pytest.fixture(scope='module')
def rig_log(config, settings):
    return run_rig(config, settings, DURATION_S, germ=np.array([[1.1, 0.05], [0.05, 0.9]]))


def _samples_by_arrival(log, settings, channels):
    """
    [(arrival s, Sample)] of the log's sensors the filter uses, by arrival (then sensor).

    Built here from the rig's settings, not by the offline filter's reader: sample k (0, 1,
    ...) of a sensor of rate r and delay d is stamped (k + 1) / r and arrives d later; its
    values are the log's k-th readings of the channels among ``channels``.
    """
    rows = []
    for sensor, samples in log.sensors.items():
        used = [c for c in samples.values if c in channels]
        if not used:
            continue
        spec = getattr(settings.sensors, sensor)
        for k in range(samples.arrival_s.size):
            stamp = (k + 1) / spec.rate_hz
            rows.append((stamp + spec.delay_s, sensor, stamp,
                         {c: float(samples.values[c][k]) for c in used}))
        assert (samples.arrival_s.size + 1) / spec.rate_hz + spec.delay_s > log.duration_s
    return [(arrival, Sample(sensor, stamp, values))
            for arrival, sensor, stamp, values in sorted(rows, key=lambda row: row[:2])]


@pytest.mark.parametrize('separate_process', [False, True])
def test_the_twin_analyses_exactly_what_the_offline_filter_does(config, settings, rig_log,
                                                                separate_process):
    """
    The engine fed a log's samples as they arrive has the offline filter's members.

    One model step a tick: the same analyses and bit speeds to the last bit. The offline
    filter runs without its open-loop copies, so that both batches have the same 4 members:
    with them (8) BLAS may sum in another order, and the stick-slip grows that rounding (a
    difference of 1e-15 at one analysis can reach 1e-8 within a second).
    """
    _engine_against_offline(config, settings, rig_log, separate_process)


@pytest.mark.parametrize('separate_process', [False, True])
def test_the_twin_estimates_the_law_as_the_offline_filter_does(config, settings, rig_log,
                                                               separate_process):
    """
    With parameters 'law' too (the members' own a1 ... a5, in the worker process as well).

    The same members and analyses as offline, the law's factors among them.
    """
    law = replace(settings, filter=replace(settings.filter, parameters='law'))
    analyses, offline = _engine_against_offline(config, law, rig_log, separate_process)
    np.testing.assert_array_equal([a.law_mean for a in analyses], offline['law_mean'])
    assert np.all(np.isfinite(offline['law_mean']))
    assert not np.allclose(offline['law_mean'][-1], offline['law_mean'][0])


@pytest.mark.parametrize('separate_process', [False, True])
def test_the_twin_runs_the_hole_rate_windows_as_the_offline_filter_does(
        config, settings, rig_log, separate_process):
    """With ``hole_rate_window_s`` (0.5 s windows): the same analyses, the windows among them."""
    windows = replace(settings, filter=replace(settings.filter, hole_rate_window_s=0.5))
    analyses, offline = _engine_against_offline(config, windows, rig_log, separate_process)
    closed = [a for a in analyses if math.isfinite(a.hole_rate_observed_m_per_s)]
    assert len(closed) >= 3
    np.testing.assert_array_equal([a.hole_rate_predicted_m_per_s for a in analyses],
                                  offline['hole_rate_predicted'])


def _engine_against_offline(config, settings, rig_log, separate_process):
    """Run the engine over the log's samples and compare with run_filter; (analyses, offline)."""
    spec = settings.filter
    offline = run_filter(config, settings, rig_log, open_loop=False).arrays()
    engine = TwinEngine(config, EnsembleSettings(
        members=spec.members, dispersion=spec.prior_dispersion, seed=spec.seed,
        separate_process=separate_process, assimilation=settings))
    try:
        arrivals = _samples_by_arrival(rig_log, settings, spec.measurements)
        analyses, speeds, dt = [], {}, engine.dt
        for _ in range(int(round(DURATION_S / dt)) + 1):
            while arrivals and arrivals[0][0] <= engine.time_s + dt + 1e-9:
                assert engine.offer_measurement(arrivals.pop(0)[1]) is None
            snapshot = engine.advance(1)
            analyses += snapshot.analyses
            ensemble = engine._ensemble_latest
            speeds[round(ensemble.time_s / dt)] = ensemble.bit[:, 4].copy()
    finally:
        engine.close()
    compared = 0
    for time_s, filtered in zip(offline['time_s'], offline['filtered']):
        if round(time_s / dt) in speeds:
            np.testing.assert_array_equal(speeds[round(time_s / dt)], filtered)
            compared += 1
    assert compared >= 0.9 * DURATION_S * 20                       # the truth's 20 Hz
    assert len(analyses) == offline['nis'].size >= 8
    np.testing.assert_array_equal([a.time_s for a in analyses], offline['analysis_time_s'])
    np.testing.assert_array_equal([a.measurements for a in analyses], offline['measurements'])
    np.testing.assert_array_equal([a.nis for a in analyses], offline['nis'])
    np.testing.assert_array_equal([a.germ_mean for a in analyses], offline['germ_mean'])
    assert snapshot.health['measurements_used'] > 0
    assert snapshot.health['measurements_refused'] == 0
    return analyses, offline


def _filter(config, settings, members=4):
    germs = germs_for_realizations(0.2, 0, range(members))
    simulator = Simulator(config, members, germs=germs)
    return simulator, SequentialFilter(simulator, members, settings, np.random.default_rng(0))


def test_a_late_sample_is_compared_with_the_prediction_at_its_stamp(config, settings):
    """
    A late sample is compared with what the members predicted at its stamp.

    Taken at t off the step grid (interpolated) and delivered 0.3 s later: a sample equal to
    the prediction's mean there is an innovation of zero.
    """
    simulator, sequential = _filter(config, settings)
    dt = simulator.dt
    stamp = 0.1 + 0.5 * dt                           # halfway between two steps
    recorded = {}
    for _ in range(int(round(0.4 / dt))):
        simulator.step()
        o = simulator.observe()
        recorded[round(o.time_s / dt)] = o.top_torque_nm.copy()
        sequential._record()
    below = recorded[round((stamp - 0.5 * dt) / dt)]
    above = recorded[round((stamp + 0.5 * dt) / dt)]
    predicted = 0.5 * (below + above)
    np.testing.assert_allclose(sequential._prediction_at(stamp)[:, 0], predicted, rtol=1e-12)
    assert sequential.offer(Sample('top_drive', stamp, {'top_torque': predicted.mean()})) is None
    record = sequential._analyse_ready()
    assert record is not None and record.measurements == 1
    assert record.nis == pytest.approx(0.0, abs=1e-20)


@pytest.mark.parametrize('sample, words', [
    (Sample('top_drive', 0.0, {'top_torque': math.nan}), 'top_torque = nan is not finite'),
    (Sample('top_drive', math.inf, {'top_torque': 1.0}), 'stamp inf is not finite'),
    (Sample('mud_logger', 0.0, {'top_torque': 1.0}), "unknown sensor 'mud_logger'"),
    (Sample('hook', 0.0, {'top_torque': 1.0}), "carries 'top_torque', not one of its"),
    (Sample('top_drive', -50.0, {'top_torque': 1.0}), 'is older than the'),
    (Sample('top_drive', 60.0, {'top_torque': 1.0}), 'ahead of the model'),
])
def test_a_bad_sample_is_refused_with_its_reason(config, settings, sample, words):
    simulator, sequential = _filter(config, settings)
    simulator.step()
    problem = sequential.offer(sample)
    assert problem is not None and words in problem
    assert sequential.samples_refused == 1 and sequential.take_refusals() == [problem]
    assert sequential._pending == []


def test_the_engine_refuses_bad_samples_and_goes_on_in_open_loop(config, settings):
    """
    A refused sample is an event with its reason and a count in health.

    The ensemble goes on (no analysis without samples); a twin without a filter refuses
    samples.
    """
    engine = TwinEngine(config, EnsembleSettings(members=4, dispersion=0.1,
                                                 assimilation=settings))
    try:
        assert engine.offer_measurement(Sample('top_drive', 0.0, {'top_torque': math.nan}))
        snapshot = engine.advance(2)
        events = [e for e in snapshot.events if e.kind == 'measurement_rejected']
        assert len(events) == 1 and 'not finite' in events[0].values['reason']
        assert snapshot.health['measurements_refused'] == 1
        for _ in range(int(0.5 / engine.dt)):
            snapshot = engine.advance(1)
            assert not snapshot.analyses
        assert np.all(np.isfinite(engine._ensemble_latest.bit))
    finally:
        engine.close()
    engine = TwinEngine(config, EnsembleSettings(members=4))
    try:
        assert 'does not assimilate' in engine.offer_measurement(
            Sample('top_drive', 0.0, {'top_torque': 1.0}))
    finally:
        engine.close()


def test_an_ensemble_filter_needs_two_members(settings):
    with pytest.raises(ValueError, match='assimilation needs >= 2'):
        EnsembleSettings(members=1, assimilation=settings)


def test_an_analysis_that_cannot_be_made_is_skipped_with_a_reason(config, settings):
    """A member predicting NaN: the analysis is skipped and said so; nothing is written."""
    simulator, sequential = _filter(config, settings)
    for _ in range(3):
        simulator.step()
        sequential._record()
    sequential._predicted[:, 1, 0] = np.nan
    q = simulator.state.q.copy()
    assert sequential.offer(Sample('top_drive', simulator.time_s, {'top_torque': 1e3})) is None
    assert sequential._analyse_ready() is None
    (why,) = sequential.take_refusals()
    assert 'skipped' in why and 'not finite' in why and '1 sample(s) unused' in why
    np.testing.assert_array_equal(simulator.state.q, q)
    assert sequential.analyses == 0 and sequential.samples_used == 0


@pytest.mark.parametrize('walk', [0.0, 0.02])
def test_the_filter_estimates_the_laws_factors_and_publishes_them(config, walk):
    """
    Parameters 'law': an analysis moves the factors of a1 ... a5, published as the law topics.

    The record holds the factors' mean and percentiles (no law topics for parameters
    'germ'); a torque at the members' largest prediction changes the factors. With
    ``parameter_walk_std`` no parameter is left without spread.
    """
    from drill_twin.assimilation.state import law_scales_for_members
    from drill_twin.ros import messages
    settings = load_assimilation(None, [
        'assimilation.filter.members=6', 'assimilation.filter.parameters=law',
        'assimilation.filter.model_error_bit_speed_rad_per_s=0.0',
        'assimilation.filter.increment_duration_s=0.0',     # the members at once: compared
        f'assimilation.filter.parameter_walk_std={walk!r}',
        'assimilation.filter.measurements=[top_torque]'])
    spec = settings.filter
    scales = law_scales_for_members(spec.law_prior_log_std, spec.seed, 6)
    simulator = Simulator(config, 6, germs=germs_for_realizations(0.2, 0, range(6)),
                          law_scales=scales)
    sequential = SequentialFilter(simulator, 6, settings, np.random.default_rng(0))
    for _ in range(20):
        simulator.step()
        sequential._record()
    before = sequential.state.extract()[:, -8:]
    predicted = sequential._prediction_at(simulator.time_s)[:, 0]
    sequential.offer(Sample('top_drive', simulator.time_s, {'top_torque': predicted.max()}))
    record = sequential._analyse_ready()
    after = sequential.state.extract()[:, -8:]
    factors = simulator.integrator.law_scales[:6]
    np.testing.assert_allclose(record.law_mean, factors.mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(record.law_lower, np.quantile(factors, 0.025, axis=0), rtol=1e-12)
    np.testing.assert_allclose(record.law_upper, np.quantile(factors, 0.975, axis=0), rtol=1e-12)
    germs = simulator.integrator.germ[:6]
    entries = np.stack([germs[:, 0, 0], germs[:, 0, 1], germs[:, 1, 1]], axis=1)
    for published, level in ((record.germ_lower, 0.025), (record.germ_upper, 0.975)):
        np.testing.assert_allclose(published, np.quantile(entries, level, axis=0), rtol=1e-12)
    assert np.all(np.ptp(factors, axis=0) > 0) and np.all(np.ptp(entries, axis=0) > 0)
    assert not np.allclose(after[:, 3:], before[:, 3:])                # the law was analysed
    if walk:
        assert np.all(after.std(axis=0) > 0)
    published = messages.law_messages(record)
    assert [topic for topic, _ in published] == [
        '/drill_twin/assimilation/law/mean', '/drill_twin/assimilation/law/lower',
        '/drill_twin/assimilation/law/upper']
    assert published[0][1].layout.dim[0].label == 'a1,a2,a3,a4,a5'
    np.testing.assert_allclose(published[0][1].data, record.law_mean)
    germ_only = SequentialFilter(simulator, 6, load_assimilation(None, [
        'assimilation.filter.members=6', 'assimilation.filter.measurements=[top_torque]',
        'assimilation.filter.parameters=germ']),
        np.random.default_rng(0))
    simulator.step()
    germ_only._record()
    germ_only.offer(Sample('top_drive', simulator.time_s, {'top_torque': predicted.max()}))
    assert messages.law_messages(germ_only._analyse_ready()) == []


def _law_filter(config, overrides):
    """
    Return a 6-member filter of the law's factors on the surface torque, 10 steps recorded.

    Its analyses write their whole increment at once (test_analysis_increment.py: in parts).
    """
    settings = load_assimilation(None, [
        'assimilation.filter.members=6', 'assimilation.filter.parameters=law',
        'assimilation.filter.increment_duration_s=0.0',
        'assimilation.filter.model_error_bit_speed_rad_per_s=0.0',
        'assimilation.filter.parameter_walk_std=0.0',
        'assimilation.filter.measurements=[top_torque]', *overrides])
    simulator = Simulator(config, 6, germs=germs_for_realizations(0.2, 0, range(6)),
                          law_scales=np.exp(0.1 * np.random.default_rng(1).standard_normal(
                              (6, 5))))
    sequential = SequentialFilter(simulator, 6, settings, np.random.default_rng(0))
    for _ in range(10):
        simulator.step()
        sequential._record()
    return simulator, sequential


def test_the_parameter_walk_is_centred_and_spreads_the_parameters(config):
    """
    The walk's kicks keep the parameters' mean of the walk-free analysis and widen the spread.

    The same deterministic (ETKF) analysis with and without the walk.
    """
    runs = {}
    for walk in (0.0, 0.05):
        simulator, sequential = _law_filter(config, [
            'assimilation.filter.method=etkf',
            f'assimilation.filter.parameter_walk_std={walk!r}'])
        predicted = sequential._prediction_at(simulator.time_s)[:, 0]
        sequential.offer(Sample('top_drive', simulator.time_s, {'top_torque': predicted.mean()}))
        sequential._analyse_ready()
        runs[walk] = sequential.state.extract()[:, -8:]
    np.testing.assert_allclose(runs[0.05].mean(axis=0), runs[0.0].mean(axis=0), atol=1e-9)
    spread_walk = np.sum((runs[0.05] - runs[0.05].mean(axis=0)) ** 2)
    spread = np.sum((runs[0.0] - runs[0.0].mean(axis=0)) ** 2)
    assert spread_walk > spread


def test_the_parameters_take_their_own_inflation(config):
    """
    With parameter_inflation the state is analysed as before and the parameters' change scales.

    The same deterministic analysis at inflation 1.5, the parameters at the state's inflation
    and at their own 1.0: the reduced coordinates and rates agree, the parameters' change
    from their forecast mean is the first run's divided by 1.5 (filter.analyse's definition).
    (The hole's offset of a member on bottom is set by the write-back, with its law.)
    """
    runs = {}
    for own in ('null', '1.0'):
        simulator, sequential = _law_filter(config, [
            'assimilation.filter.inflation=1.5', 'assimilation.filter.relaxation=0.3',
            f'assimilation.filter.parameter_inflation={own}'])
        forecast = sequential.state.extract()
        predicted = sequential._prediction_at(simulator.time_s)[:, 0]
        sequential.offer(Sample('top_drive', simulator.time_s, {'top_torque': predicted.mean()
                                                                + 2 * predicted.std()}))
        assert sequential._analyse_ready() is not None
        runs[own] = forecast, sequential.state.extract()
    (forecast, shared), (_, separate) = runs['null'], runs['1.0']
    count = 8                                        # the germ's 3 coordinates and 5 factors
    rates_end = shared.shape[1] - count - 1                       # q, q' (then the offset)
    np.testing.assert_allclose(separate[:, :rates_end], shared[:, :rates_end], rtol=1e-12,
                               atol=1e-12)
    mean = forecast[:, -count:].mean(axis=0)
    change = shared[:, -count:] - mean
    assert np.max(np.abs(change)) > 1e-3                                 # the law was analysed
    np.testing.assert_allclose(separate[:, -count:] - mean, change / 1.5, atol=1e-12)


def test_localisation_by_motion_analyses_each_motion_with_its_own_channels(config):
    """
    With ``localisation: motion`` each motion's block takes the analysis of its channels only.

    One torque and one block-position sample, analysed together (ETKF: deterministic). The
    axial block's coordinates and rates are those of the analysis of the block position
    alone, the torsional block's those of the torque alone, the parameters those of both
    (filter.analyse computed here from the members' predictions); the buffer of predictions
    takes the transform of each channel's motion. Without localisation the same samples move
    the axial block otherwise (the torque's sampling correlation with it).
    """
    from drill_twin.assimilation.filter import analyse
    runs = {}
    for localisation in ('none', 'motion'):
        simulator, sequential = _law_filter(config, [
            'assimilation.filter.method=etkf', 'assimilation.filter.inflation=1.1',
            'assimilation.filter.relaxation=0.3',
            'assimilation.filter.measurements=[top_torque,block_position]',
            f'assimilation.filter.localisation={localisation}'])
        forecast, buffer = sequential.state.extract(), sequential._predicted.copy()
        now = simulator.time_s
        predicted = sequential._prediction_at(now)
        measured = predicted.mean(axis=0) + 1.5 * predicted.std(axis=0)
        sequential.offer(Sample('top_drive', now, {'top_torque': measured[0]}))
        sequential.offer(Sample('hook', now, {'block_position': measured[1]}))
        assert sequential._analyse_ready().measurements == 2
        runs[localisation] = sequential.state.extract()
    spec = sequential.settings.filter
    variance = [sequential.settings.channel(c).std(predicted[:, k].mean()) ** 2
                for k, c in enumerate(('top_torque', 'block_position'))]

    def transform(rows):
        result = analyse(predicted[:, rows], measured[rows], np.asarray(variance)[rows],
                         inflation=spec.inflation, relaxation=spec.relaxation,
                         parameter_inflation=spec.parameter_inflation)
        return result.transform, result.parameter_transform

    axial_t, _ = transform([1])
    torsional_t, _ = transform([0])
    _, parameter_t = transform([0, 1])
    columns = sequential.state.motion_columns()
    axial = columns['axial'][:-1]                        # the offset is set by the write-back
    analysed = runs['motion']
    np.testing.assert_allclose(analysed[:, axial], axial_t @ forecast[:, axial],
                               rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(analysed[:, columns['torsional']],
                               torsional_t @ forecast[:, columns['torsional']],
                               rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(analysed[:, -8:], parameter_t @ forecast[:, -8:], rtol=1e-10,
                               atol=1e-12)
    np.testing.assert_allclose(sequential._predicted[:, :, 0],
                               np.matmul(torsional_t, buffer[:, :, 0:1])[..., 0], rtol=1e-10)
    np.testing.assert_allclose(sequential._predicted[:, :, 1],
                               np.matmul(axial_t, buffer[:, :, 1:2])[..., 0], rtol=1e-10)
    moved = np.abs(runs['none'][:, axial] - analysed[:, axial]).max()
    assert moved > 1e-6 * np.abs(forecast[:, axial]).max()
