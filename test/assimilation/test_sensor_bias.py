"""
Sensor biases in the filter: a known calibration offset subtracted, an unknown one estimated.

A rig's reading is the value plus the sensor's bias plus noise (:mod:`.measurements`). The
filter subtracts a channel's configured ``bias`` from every reading, and with
``bias_prior_std`` > 0 estimates a constant bias beyond it as an augmented parameter of each
member (:mod:`drill_twin.assimilation.sequential`).
"""
from __future__ import annotations

import numpy as np
import pytest

from drill_twin.assimilation.measurements import channel_values
from drill_twin.assimilation.rig_emulator import run_rig
from drill_twin.assimilation.sequential import Sample, SequentialFilter
from drill_twin.assimilation.settings import load_assimilation
from drill_twin.config import ConfigError, load_config
from drill_twin.integrator.simulator import Simulator
from drill_twin.uncertainty.germ import germs_for_realizations

SMALL = ['sections.drill_pipe.elements=8', 'sections.drill_collar.elements=4',
         'reduced_basis.lateral_modes=6']
MEMBERS = 6


@pytest.fixture(scope='module')
def config():
    return load_config(None, SMALL)


def _filter(config, overrides, steps=10):
    """
    Return a 6-member filter of the surface torque and TOB (no walk or model error), steps run.

    (The TOB makes a surface torque's bias observable with the law estimated: settings.)
    """
    settings = load_assimilation(None, [
        f'assimilation.filter.members={MEMBERS}', 'assimilation.filter.method=etkf',
        'assimilation.filter.model_error_bit_speed_rad_per_s=0.0',
        'assimilation.filter.parameter_walk_std=0.0',
        'assimilation.filter.measurements=[top_torque,torque_on_bit]',
        'assimilation.channels.top_torque.bias_walk_std=0.0', *overrides])
    simulator = Simulator(config, MEMBERS, germs=germs_for_realizations(0.2, 0, range(MEMBERS)),
                          law_scales=np.exp(0.1 * np.random.default_rng(1).standard_normal(
                              (MEMBERS, 5))))
    sequential = SequentialFilter(simulator, MEMBERS, settings, np.random.default_rng(0))
    for _ in range(steps):
        simulator.step()
        sequential.after_step()
    return simulator, sequential


def test_a_known_bias_is_subtracted_from_every_reading(config):
    """
    A reading of a sensor with a known offset b analyses as the reading minus b without it.

    The same members, the reading r + 300 N m with the channel's bias 300, and r with 0: the
    analysed states agree (to the rounding of r + 300 - 300); r + 300 with bias 0 does not.
    """
    states = {}
    for bias, offset in ((300.0, 300.0), (0.0, 0.0), (0.0, 300.0)):
        simulator, sequential = _filter(config, [
            f'assimilation.channels.top_torque.bias={bias!r}'])
        predicted = sequential._prediction_at(simulator.time_s)[:, 0]
        reading = predicted.mean() + 2.0 * predicted.std() + offset
        sequential.offer(Sample('top_drive', simulator.time_s, {'top_torque': reading}))
        assert sequential._analyse_ready() is not None
        states[bias, offset] = sequential.state.extract()
    np.testing.assert_allclose(states[300.0, 300.0], states[0.0, 0.0], rtol=1e-9, atol=1e-12)
    assert not np.allclose(states[0.0, 300.0], states[0.0, 0.0], rtol=1e-6)


def test_an_estimated_bias_is_each_members_offset_of_its_prediction(config):
    """
    Each member predicts its model's torque plus its own bias; the prior is centred.

    The prior's spread is ``bias_prior_std`` (the sample standard deviation of 6 draws: within
    a factor of 3 of it).
    """
    simulator, sequential = _filter(config, [
        'assimilation.channels.top_torque.bias_prior_std=200.0'])
    assert sequential.bias_channels == ('top_torque',)
    bias = sequential.channel_bias[:, 0]
    assert abs(bias.mean()) < 1e-9
    assert 200.0 / 3 < bias.std(ddof=1) < 3 * 200.0
    model = channel_values(simulator.observe(detailed=MEMBERS), 'top_torque', MEMBERS)
    np.testing.assert_allclose(sequential._prediction_at(simulator.time_s)[:, 0],
                               model + bias, rtol=1e-12)


def test_the_bias_takes_the_kalman_update_of_the_augmented_state(config):
    """
    The analysed biases are the Kalman filter's on the ensemble's statistics (ETKF is exact).

    The forecast biases b (N,) and predictions Y = model + b (N,) give the gain
    K = cov(b, Y) / (var Y + R): the analysed mean is mean b + K (y - mean Y), the analysed
    variance (1 - K cov(b, Y) / var b) var b. With the RTPP weight r (the parameters'
    relaxation is the state's here) the mean is the same and the anomalies are
    (1 - r) times those analysed without it plus r times the forecast's.
    """
    analysed = {}
    for relaxation in (0.0, 0.5):
        simulator, sequential = _filter(config, [
            'assimilation.channels.top_torque.bias_prior_std=200.0',
            'assimilation.channels.top_torque.noise_relative=0.0',
            'assimilation.channels.top_torque.noise_std=80.0',
            f'assimilation.filter.relaxation={relaxation!r}'])
        b = sequential.channel_bias[:, 0].copy()
        model = channel_values(simulator.observe(detailed=MEMBERS), 'top_torque', MEMBERS)
        Y = model + b
        reading = Y.mean() + 150.0
        sequential.offer(Sample('top_drive', simulator.time_s, {'top_torque': reading}))
        assert sequential._analyse_ready() is not None
        analysed[relaxation] = sequential.channel_bias[:, 0].copy()
    cov = np.cov(b, Y)
    gain = cov[0, 1] / (cov[1, 1] + 80.0 ** 2)
    for values in analysed.values():
        np.testing.assert_allclose(values.mean(), b.mean() + gain * (reading - Y.mean()),
                                   rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(np.var(analysed[0.0], ddof=1),
                               cov[0, 0] - gain * cov[0, 1], rtol=1e-9)
    np.testing.assert_allclose(analysed[0.5] - analysed[0.5].mean(),
                               0.5 * (analysed[0.0] - analysed[0.0].mean())
                               + 0.5 * (b - b.mean()), rtol=1e-9, atol=1e-9)


def test_with_the_law_known_the_surface_torques_offset_is_found_as_the_bias(config):
    """
    Truth and filter share the law and the germ; the rig's torque sensor reads 400 N m high.

    The surface torque's only discrepancy is then the sensor's offset: the estimated bias
    (the law not estimated: parameters 'none') reaches it within its bounds after 2 s of
    10 Hz torque readings, while the prior's mean was 0.
    """
    truth_bias = 400.0
    germ = np.array([[1.0, 0.0], [0.0, 1.0]])
    rig_settings = load_assimilation(None, [
        f'assimilation.channels.top_torque.bias={truth_bias!r}'])
    log = run_rig(config, rig_settings, 2.0, germ=germ)
    settings = load_assimilation(None, [
        f'assimilation.filter.members={MEMBERS}', 'assimilation.filter.parameters=none',
        'assimilation.filter.analysis_rate_hz=5.0',
        'assimilation.filter.measurements=[top_torque]',
        'assimilation.channels.top_torque.bias_prior_std=300.0'])
    simulator = Simulator(config, MEMBERS, germs=np.repeat(germ[None], MEMBERS, axis=0))
    sequential = SequentialFilter(simulator, MEMBERS, settings, np.random.default_rng(0))
    from drill_twin.assimilation.offline import _sample
    k, stamps = 0, log.sensors['top_drive'].stamp_s
    records = []
    while simulator.time_s < 2.0 - 1e-9:
        simulator.step()
        while k < stamps.size and stamps[k] <= simulator.time_s + 1e-9:
            sequential.offer(_sample(log, 'top_drive', k, ('top_torque',)))
            k += 1
        record = sequential.after_step()
        if record is not None:
            records.append(record)
    last = records[-1]
    assert last.bias_channels == ('top_torque',)
    assert abs(last.bias_mean[0] - truth_bias) < 0.15 * truth_bias
    assert last.bias_lower[0] <= truth_bias <= last.bias_upper[0]


@pytest.mark.parametrize('item, key', [
    ('assimilation.channels.top_torque.bias_prior_std=-1', 'bias_prior_std'),
    ('assimilation.channels.top_torque.bias=.nan', 'bias'),
    ('assimilation.channels.top_torque.bias_prior_std=100', 'needs torque_on_bit'),
    ('assimilation.channels.hook_load.bias_prior_std=100', 'top_torque or torque_on_bit only'),
])
def test_a_bad_bias_setting_names_its_key(item, key):
    """Also a bias the filter's measurements cannot tell from the law (the law estimated)."""
    overrides = [item]
    if 'hook_load' in item:
        overrides.append('assimilation.filter.measurements=[top_torque,hook_load]')
    with pytest.raises(ConfigError, match=key):
        load_assimilation(None, overrides)
    if 'needs' in key:                      # with the TOB, or the law not estimated: accepted
        load_assimilation(None, [item, 'assimilation.filter.parameters=none'])
        load_assimilation(None, [item, 'assimilation.filter.measurements='
                                       '[top_torque,block_position,torque_on_bit]'])


def test_the_estimated_bias_is_recorded_and_published_labelled_by_channel(config):
    """The record's bias is the members' mean and percentiles; the twin's three topics carry it."""
    from drill_twin.ros import messages
    simulator, sequential = _filter(config, [
        'assimilation.channels.top_torque.bias_prior_std=200.0'])
    predicted = sequential._prediction_at(simulator.time_s)[:, 0]
    sequential.offer(Sample('top_drive', simulator.time_s, {'top_torque': predicted.max()}))
    record = sequential._analyse_ready()
    bias = sequential.channel_bias[:, 0]
    assert record.bias_channels == ('top_torque',)
    np.testing.assert_allclose(record.bias_mean, [bias.mean()], rtol=1e-12)
    np.testing.assert_allclose([record.bias_lower[0], record.bias_upper[0]],
                               np.percentile(bias, [2.5, 97.5]), rtol=1e-12)
    published = messages.bias_messages(record)
    assert [topic for topic, _ in published] == [
        '/drill_twin/assimilation/bias/mean', '/drill_twin/assimilation/bias/lower',
        '/drill_twin/assimilation/bias/upper']
    assert published[0][1].layout.dim[0].label == 'top_torque'
    np.testing.assert_allclose([m.data[0] for _, m in published],
                               [record.bias_mean[0], record.bias_lower[0], record.bias_upper[0]])
    simulator, unbiased = _filter(config, [])
    predicted = unbiased._prediction_at(simulator.time_s)[:, 0]
    unbiased.offer(Sample('top_drive', simulator.time_s, {'top_torque': predicted.max()}))
    assert messages.bias_messages(unbiased._analyse_ready()) == []


def test_the_bias_walk_is_centred_and_moves_the_stored_predictions_alike(config):
    """
    bias_walk_std: centred kicks of that size after the analysis, in the buffer as well.

    The same deterministic analysis without and with a walk of 50 N m: the biases' mean is
    the same, their changes have a sample std near 50 (6 members: within a factor 3), and each
    member's stored prediction at the analysis moves by its kick.
    """
    runs = {}
    for walk in (0.0, 50.0):
        simulator, sequential = _filter(config, [
            'assimilation.channels.top_torque.bias_prior_std=200.0',
            f'assimilation.channels.top_torque.bias_walk_std={walk!r}'])
        predicted = sequential._prediction_at(simulator.time_s)[:, 0]
        sequential.offer(Sample('top_drive', simulator.time_s, {'top_torque': predicted.max()}))
        assert sequential._analyse_ready() is not None
        runs[walk] = (sequential.channel_bias[:, 0].copy(),
                      sequential._prediction_at(simulator.time_s)[:, 0].copy())
    (still, stored_still), (walked, stored_walked) = runs[0.0], runs[50.0]
    kicks = walked - still
    assert abs(kicks.mean()) < 1e-9
    assert 50.0 / 3 < kicks.std(ddof=1) < 3 * 50.0
    np.testing.assert_allclose(stored_walked - stored_still, kicks, rtol=1e-9, atol=1e-9)
