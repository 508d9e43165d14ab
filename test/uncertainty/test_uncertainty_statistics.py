"""Monte Carlo statistics: envelopes, Fourier moduli, coefficients of variation, Eq. 54."""
import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import stats

from drill_twin.uncertainty.statistics import (
    coefficient_of_variation, coefficient_of_variation_of_time_average,
    coefficient_of_variation_per_instant, envelope, fourier_modulus,
    mean_coefficient_of_variation_per_instant, mean_square_convergence, spectral_envelope,
    time_integral_of_squared_norm)


@pytest.fixture
def rng():
    return np.random.default_rng(865)


def test_envelope_of_normal_samples(rng):
    n = 200_000
    samples = rng.standard_normal((n, 3))
    mean, lower, upper = envelope(samples)
    assert mean.shape == lower.shape == upper.shape == (3,)
    assert np.all((lower < mean) & (mean < upper))
    # standard error of a p-quantile: sqrt(p (1-p) / n) / pdf(q_p), ~0.0068 at p = 0.975
    q = stats.norm.ppf(0.975)
    standard_error = np.sqrt(0.975 * 0.025 / n) / stats.norm.pdf(q)
    assert_allclose(upper, q, atol=5.0 * standard_error)
    assert_allclose(lower, -q, atol=5.0 * standard_error)
    assert_allclose(mean, 0.0, atol=5.0 / np.sqrt(n))


def test_envelope_of_uniform_grid_is_exact():
    samples = np.linspace(0.0, 1.0, 1001)[:, None] * np.array([1.0, 2.0])
    mean, lower, upper = envelope(samples, 0.1, 0.9)
    assert_allclose(mean, [0.5, 1.0])
    assert_allclose(lower, [0.1, 0.2])
    assert_allclose(upper, [0.9, 1.8])


@pytest.mark.parametrize('lower, upper', [(0.5, 0.5), (0.9, 0.1), (-0.1, 0.5), (0.1, 1.1)])
def test_envelope_rejects_bad_probabilities(lower, upper):
    with pytest.raises(ValueError):
        envelope(np.zeros((3, 2)), lower, upper)


DT = 0.01
N_TIME = 5000  # T = 50 s, as the paper's stationary window 200-250 s
FREQUENCY = 0.84  # on a bin: 0.84 * 50 = 42


def _sinusoid(amplitude, offset=0.0):
    t = np.arange(N_TIME) * DT
    return offset + amplitude * np.cos(2.0 * np.pi * FREQUENCY * t + 0.3)


def test_fourier_modulus_transform_scaling():
    frequency, modulus = fourier_modulus(_sinusoid(2.0, offset=1.0), DT)
    assert frequency.shape == modulus.shape == (N_TIME // 2 + 1,)
    assert frequency[1] == pytest.approx(1.0 / (N_TIME * DT))
    peak = np.argmax(modulus[1:]) + 1
    assert frequency[peak] == pytest.approx(FREQUENCY)
    assert modulus[peak] == pytest.approx(2.0 * N_TIME * DT / 2.0)  # A T / 2
    assert modulus[0] == pytest.approx(1.0 * N_TIME * DT)  # mean * T
    off_peak = np.delete(modulus, [0, peak])
    assert np.all(off_peak < 1e-9 * modulus[peak])


def test_fourier_modulus_amplitude_scaling_and_window():
    signal = _sinusoid(2.0, offset=1.0)
    frequency, modulus = fourier_modulus(signal, DT, scaling='amplitude')
    peak = np.argmax(modulus[1:]) + 1
    assert modulus[peak] == pytest.approx(2.0)
    assert modulus[0] == pytest.approx(1.0)
    _, tapered = fourier_modulus(signal, DT, window=np.hanning(N_TIME), scaling='amplitude')
    assert tapered[peak] == pytest.approx(2.0, rel=1e-3)


def test_fourier_modulus_nyquist_line_in_amplitude_scaling():
    signal = np.cos(np.pi * np.arange(8))  # +1, -1, ...: the Nyquist line, amplitude 1
    _, modulus = fourier_modulus(signal, DT, scaling='amplitude')
    assert_allclose(modulus, [0, 0, 0, 0, 1.0], atol=1e-12)


def test_fourier_modulus_batch_matches_single(rng):
    batch = rng.standard_normal((4, 3, 64))
    _, moduli = fourier_modulus(batch, DT)
    _, single = fourier_modulus(batch[2, 1], DT)
    assert moduli.shape == (4, 3, 33)
    assert_allclose(moduli[2, 1], single)


def test_fourier_modulus_rejects_bad_arguments():
    with pytest.raises(ValueError):
        fourier_modulus(np.zeros(8), 0.0)
    with pytest.raises(ValueError):
        fourier_modulus(np.zeros(8), DT, scaling='psd')
    with pytest.raises(ValueError):
        fourier_modulus(np.zeros(8), DT, window=np.ones(7))


def test_spectral_envelope_brackets_the_amplitudes():
    amplitudes = np.linspace(1.0, 3.0, 41)
    samples = amplitudes[:, None] * _sinusoid(1.0)[None, :]
    frequency, band = spectral_envelope(samples, DT, scaling='amplitude')
    peak = np.argmin(np.abs(frequency - FREQUENCY))
    assert band.mean[peak] == pytest.approx(2.0)
    assert band.lower[peak] == pytest.approx(np.quantile(amplitudes, 0.025))
    assert band.upper[peak] == pytest.approx(np.quantile(amplitudes, 0.975))


def test_coefficient_of_variation_known_values():
    values = np.array([[1.0, -2.0], [2.0, -4.0], [3.0, -6.0]])
    # mean (2, -4), sample std (1, 2)
    assert_allclose(coefficient_of_variation(values), [0.5, 0.5])
    assert_allclose(coefficient_of_variation(values, ddof=0), np.sqrt(2.0 / 3.0) / 2.0)
    assert_allclose(coefficient_of_variation(values.T, axis=1), [0.5, 0.5])
    assert coefficient_of_variation(np.array([-1.0, 1.0])) == np.inf


def test_time_average_and_per_instant_cov_differ_as_constructed():
    # realization s: 10 + s * (-1)^t ... anti-phase oscillations average out in time,
    # so the time averages agree exactly while each instant is dispersed.
    n_time = 6
    sign = (-1.0) ** np.arange(n_time)
    offsets = np.array([-1.0, 0.0, 1.0])
    samples = 10.0 + offsets[:, None] * sign[None, :]
    assert_allclose(coefficient_of_variation_of_time_average(samples), 0.0, atol=1e-15)
    per_instant = coefficient_of_variation_per_instant(samples)
    assert per_instant.shape == (n_time,)
    assert_allclose(per_instant, 0.1)  # sample std 1 over mean 10
    assert_allclose(mean_coefficient_of_variation_per_instant(samples), 0.1)


def test_time_average_cov_of_levels():
    # realization s has level 2 + s plus a zero-mean ripple; per-component shape kept.
    t = np.arange(100) * DT
    ripple = np.sin(2.0 * np.pi * t / (100 * DT))
    levels = np.array([1.0, 2.0, 3.0])
    samples = np.stack([levels[:, None] + ripple, -2.0 * levels[:, None] + ripple], axis=1)
    assert samples.shape == (3, 2, 100)
    assert_allclose(coefficient_of_variation_of_time_average(samples), [0.5, 0.5])
    assert mean_coefficient_of_variation_per_instant(samples).shape == (2,)


def test_time_integral_of_squared_norm():
    t = np.linspace(0.0, 2.0, 201)
    dt = t[1] - t[0]
    # ||u||^2 = t + 9: linear, so the trapezoid rule is exact: T^2 / 2 + 9 T = 20
    u = np.stack([np.sqrt(t), np.full_like(t, 3.0)])
    assert time_integral_of_squared_norm(u, dt) == pytest.approx(20.0)
    batch = np.stack([u, 2.0 * u])
    assert_allclose(time_integral_of_squared_norm(batch, dt), [20.0, 80.0])
    with pytest.raises(ValueError):
        time_integral_of_squared_norm(t, dt)


def test_mean_square_convergence_is_running_mean(rng):
    values = np.array([2.0, 4.0, 0.0, 6.0])
    assert_allclose(mean_square_convergence(values), [2.0, 3.0, 2.0, 3.0])
    batch = rng.random((50, 3))
    conv = mean_square_convergence(batch)
    for n_s in (1, 17, 50):
        assert_allclose(conv[n_s - 1], batch[:n_s].mean(axis=0))
