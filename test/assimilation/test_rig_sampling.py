"""
The rig emulator's samples are stamped at the rig's sampling times and arrive a delay later.

A sensor of rate r and delay d samples at k / r (k = 1, 2, ...) and each sample arrives d later;
a log of length D holds those that have arrived by D. The expected stamps are counted here
from the settings; with noise-free sensors a downhole sample is the truth at its stamp (the
mud-pulse value is the bit's when sampled, not when it reaches the surface).
"""
from __future__ import annotations

import numpy as np
import pytest

from drill_twin.assimilation.measurements import SENSOR_CHANNELS
from drill_twin.assimilation.rig_emulator import run_rig
from drill_twin.assimilation.settings import load_assimilation
from drill_twin.config import load_config

SMALL = ['sections.drill_pipe.elements=8', 'sections.drill_collar.elements=4',
         'reduced_basis.lateral_modes=6', 'integration.time_step_s=0.005']
DURATION_S = 2.0
RATES_AND_DELAYS = {'top_drive': (10.0, 0.0), 'hook': (8.0, 0.125), 'downhole': (4.0, 0.75)}
"""(rate Hz, delay s) of each sensor: every stamp on the model's 5 ms steps."""


@pytest.fixture(scope='module')
def settings():
    overrides = [f'assimilation.channels.{channel}.{key}=0.0'
                 for channels in SENSOR_CHANNELS.values() for channel in channels
                 for key in ('noise_std', 'noise_relative')]
    for sensor, (rate, delay) in RATES_AND_DELAYS.items():
        overrides += [f'assimilation.sensors.{sensor}.rate_hz={rate}',
                      f'assimilation.sensors.{sensor}.delay_s={delay}']
    return load_assimilation(None, overrides)


@pytest.fixture(scope='module')
def log(settings):
    return run_rig(load_config(None, SMALL), settings, DURATION_S,
                   germ=np.array([[1.1, 0.05], [0.05, 0.9]]))


def _expected_stamps(rate_hz: float, delay_s: float) -> list[float]:
    """Return k / rate for k = 1, 2, ... while k / rate + delay (its arrival) is in the log."""
    stamps, k = [], 1
    while k / rate_hz + delay_s <= DURATION_S + 1e-9:
        stamps.append(k / rate_hz)
        k += 1
    return stamps


@pytest.mark.parametrize('sensor', list(RATES_AND_DELAYS))
def test_each_sample_is_stamped_at_its_sampling_time_and_arrives_its_delay_later(log, sensor):
    rate, delay = RATES_AND_DELAYS[sensor]
    expected = _expected_stamps(rate, delay)
    assert len(expected) == {'top_drive': 20, 'hook': 15, 'downhole': 5}[sensor]
    samples = log.sensors[sensor]
    np.testing.assert_allclose(samples.stamp_s, expected, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(samples.arrival_s, np.array(expected) + delay, rtol=0.0,
                               atol=1e-12)
    assert set(samples.values) == set(SENSOR_CHANNELS[sensor])
    assert all(values.shape == (len(expected),) for values in samples.values.values())


def test_a_delayed_downhole_sample_is_the_truth_at_its_stamp(log):
    """
    Noise-free downhole samples against the truth at their stamps (20 Hz: every stamp).

    The bit moves between the stamp and the arrival 0.75 s later: a sample read at its
    arrival, or stamped a step off, would differ from the truth at its stamp.
    """
    truth, samples = log.truth, log.sensors['downhole']
    steps = np.round(truth.time_s / 0.005).astype(int)
    for k, stamp in enumerate(samples.stamp_s):
        row = int(np.flatnonzero(steps == round(stamp / 0.005))[0])
        assert samples.values['bit_speed'][k] == pytest.approx(truth.bit_speed_rad_per_s[row],
                                                               rel=1e-12)
        assert samples.values['torque_on_bit'][k] == pytest.approx(truth.torque_on_bit_nm[row],
                                                                   rel=1e-12)
        assert samples.values['weight_on_bit'][k] == pytest.approx(truth.weight_on_bit_n[row],
                                                                   rel=1e-12)
    # The truth changes over a delay and over one step: the comparison can tell them apart.
    speed = np.interp(samples.stamp_s, truth.time_s, truth.bit_speed_rad_per_s)
    later = np.interp(samples.stamp_s + 0.75, truth.time_s, truth.bit_speed_rad_per_s)
    step_later = np.interp(samples.stamp_s + 0.005, truth.time_s, truth.bit_speed_rad_per_s)
    assert np.all(np.abs(later - speed) > 1e-6) and np.all(np.abs(step_later - speed) > 1e-9)
