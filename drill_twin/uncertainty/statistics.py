"""
Monte Carlo statistics of the stochastic response (paper Sect. 4.1-4.2).

Conventions: realizations on the first axis, time on the last axis, uniform time step,
SI units; arrays are (n_realizations, ..., n_time). The caller selects the stationary
window (e.g. 200-250 s) before calling.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

SPECTRUM_SCALINGS = ('transform', 'amplitude')


class Envelope(NamedTuple):
    """Mean and quantile band over realizations; each array has the sample shape[1:]."""

    mean: np.ndarray
    lower: np.ndarray
    upper: np.ndarray


def _positive_step(time_step_s: float) -> float:
    step = float(time_step_s)
    if not step > 0.0:
        raise ValueError(f'time_step_s must be > 0; got {time_step_s!r}')
    return step


def envelope(samples: np.ndarray, lower: float = 0.025, upper: float = 0.975) -> Envelope:
    """
    Mean and the [lower, upper] quantile envelope over realizations (method of quantiles).

    Quantiles are the empirical ones of numpy.quantile ('linear' interpolation between
    order statistics); with the defaults the band has probability level 0.95.

    :param samples: shape (n_realizations, ...), any unit.
    :param lower: lower probability, 0 <= lower < upper.
    :param upper: upper probability, lower < upper <= 1.

    :return: Envelope(mean, lower, upper), each of shape samples.shape[1:], in the samples' unit.
    """
    if not 0.0 <= lower < upper <= 1.0:
        raise ValueError(f'need 0 <= lower < upper <= 1; got lower={lower}, upper={upper}')
    samples = np.asarray(samples, dtype=float)
    low, high = np.quantile(samples, [lower, upper], axis=0)
    return Envelope(samples.mean(axis=0), low, high)


def fourier_modulus(
        signal: np.ndarray, time_step_s: float, window: np.ndarray | None = None,
        scaling: str = 'transform') -> tuple[np.ndarray, np.ndarray]:
    """
    One-sided modulus of the Fourier transform of uniformly sampled signals.

    With X_k = sum_m w_m x_m exp(-2 i pi k m / N) (numpy.fft.rfft, k = 0..N//2, frequency
    f_k = k / (N dt)) and the window w normalised to unit mean:

    - 'transform' (default): dt |X_k|, the discrete approximation of the modulus of the
      continuous transform |int x(t) exp(-2 i pi f t) dt| over the record, in
      [signal unit] * s. A sinusoid A cos(2 pi f_k t) with f_k a non-zero bin below Nyquist
      gives A T / 2 at f_k, T = N dt.
    - 'amplitude': the single-sided amplitude spectrum, 2 |X_k| / N for 0 < f_k < Nyquist and
      |X_k| / N at f = 0 (and at Nyquist for even N), in [signal unit]; the same sinusoid
      gives A.

    Nothing is detrended: subtract the mean first to remove the f = 0 line.

    :param signal: shape (..., n_time).
    :param time_step_s: dt in s, > 0.
    :param window: taper of shape (n_time,), e.g. numpy.hanning(n_time); None = rectangular.
        It is rescaled to unit mean (coherent gain), so sinusoid peaks keep the
        heights above when they fall on a bin.
    :param scaling: 'transform' or 'amplitude'.

    :return: frequency_hz of shape (n_time // 2 + 1,) and modulus of shape (..., n_time // 2 + 1).
    """
    step = _positive_step(time_step_s)
    if scaling not in SPECTRUM_SCALINGS:
        raise ValueError(f'scaling must be one of {SPECTRUM_SCALINGS}; got {scaling!r}')
    signal = np.asarray(signal, dtype=float)
    n_time = signal.shape[-1]
    if window is not None:
        window = np.asarray(window, dtype=float)
        if window.shape != (n_time,):
            raise ValueError(f'window must have shape ({n_time},); got {window.shape}')
        signal = signal * (window / window.mean())
    modulus = np.abs(np.fft.rfft(signal, axis=-1))
    frequency_hz = np.fft.rfftfreq(n_time, d=step)
    if scaling == 'transform':
        return frequency_hz, modulus * step
    one_sided = np.full(frequency_hz.size, 2.0)
    one_sided[0] = 1.0
    if n_time % 2 == 0:
        one_sided[-1] = 1.0
    return frequency_hz, modulus * one_sided / n_time


def spectral_envelope(
        samples: np.ndarray, time_step_s: float, lower: float = 0.025, upper: float = 0.975,
        window: np.ndarray | None = None,
        scaling: str = 'transform') -> tuple[np.ndarray, Envelope]:
    """
    Mean and quantile envelope, over realizations, of the Fourier modulus.

    The modulus is computed per realization (fourier_modulus) and the statistics taken
    frequency by frequency, as in the paper's spectra (Fig. 8b, 13b).

    :param samples: shape (n_realizations, ..., n_time).
    :param time_step_s: dt in s.
    :param lower, upper: probabilities of the band (see envelope).
    :param window, scaling: see fourier_modulus.

    :return: frequency_hz of shape (n_freq,), n_freq = n_time // 2 + 1, and an Envelope whose
        arrays have shape (..., n_freq), in the unit of the chosen scaling.
    """
    frequency_hz, modulus = fourier_modulus(samples, time_step_s, window, scaling)
    return frequency_hz, envelope(modulus, lower, upper)


def coefficient_of_variation(values: np.ndarray, axis: int = 0, ddof: int = 1) -> np.ndarray:
    """
    Compute std / |mean| along `axis` (sample std with `ddof`; 1 = unbiased variance).

    Where the mean is 0 the result is inf (nan if the std is 0 too); no warning is issued.

    :param values: any shape; realizations on `axis`.
    :param axis: the axis of realizations.
    :param ddof: delta degrees of freedom of the standard deviation.

    :return: Dimensionless array, values.shape without `axis`.
    """
    values = np.asarray(values, dtype=float)
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.std(values, axis=axis, ddof=ddof) / np.abs(np.mean(values, axis=axis))


def coefficient_of_variation_of_time_average(samples: np.ndarray, ddof: int = 1) -> np.ndarray:
    """
    Coefficient of variation across realizations of their time averages.

    Each realization is first averaged over time (all samples weighted equally), then
    std/|mean| is taken across realizations: the dispersion of a per-realization mean
    level (e.g. the mean ROP of each realization in 200-250 s).

    :param samples: shape (n_realizations, ..., n_time), the stationary window only.
    :param ddof: see coefficient_of_variation.

    :return: Dimensionless array of shape samples.shape[1:-1].
    """
    samples = np.asarray(samples, dtype=float)
    return coefficient_of_variation(samples.mean(axis=-1), axis=0, ddof=ddof)


def coefficient_of_variation_per_instant(samples: np.ndarray, ddof: int = 1) -> np.ndarray:
    """
    Coefficient of variation across realizations at each instant, std_s X / |mean_s X|.

    This is the paper's "for each time t, the coefficients of variation of WOB and TOB are
    ~5e-3" (Sect. 4.2).

    :param samples: shape (n_realizations, ..., n_time).
    :param ddof: see coefficient_of_variation.

    :return: Dimensionless array of shape samples.shape[1:] (time on the last axis).
    """
    return coefficient_of_variation(samples, axis=0, ddof=ddof)


def mean_coefficient_of_variation_per_instant(
        samples: np.ndarray, ddof: int = 1) -> np.ndarray:
    """
    Time average over the window of coefficient_of_variation_per_instant.

    :param samples: shape (n_realizations, ..., n_time), the stationary window only.
    :param ddof: see coefficient_of_variation.

    :return: Dimensionless array of shape samples.shape[1:-1].
    """
    return coefficient_of_variation_per_instant(samples, ddof).mean(axis=-1)


def time_integral_of_squared_norm(u: np.ndarray, time_step_s: float) -> np.ndarray:
    """
    int_0^t_f ||u(t)||^2 dt by the trapezoid rule, ||.|| the Euclidean norm over components.

    :param u: shape (..., n_components, n_time), e.g. (n_realizations, n_dofs, n_time).
    :param time_step_s: dt in s, > 0.

    :return: Shape u.shape[:-2], in [u unit]^2 * s.
    """
    step = _positive_step(time_step_s)
    u = np.asarray(u, dtype=float)
    if u.ndim < 2:
        raise ValueError(f'u must have shape (..., n_components, n_time); got {u.shape}')
    return np.trapezoid(np.sum(u**2, axis=-2), dx=step, axis=-1)


def mean_square_convergence(response_norm_sq_integrals: np.ndarray) -> np.ndarray:
    """
    conv(n_s) = 1/n_s sum_{j <= n_s} int ||U(t, s_j)||^2 dt (Eq. 54), for n_s = 1..N.

    :param response_norm_sq_integrals: shape (N, ...), the integral of each realization in
        the order the realizations were drawn (see time_integral_of_squared_norm).

    :return: The running mean, same shape and unit; row n_s - 1 holds conv(n_s).
    """
    values = np.asarray(response_norm_sq_integrals, dtype=float)
    counts = np.arange(1, values.shape[0] + 1).reshape((-1,) + (1,) * (values.ndim - 1))
    return np.cumsum(values, axis=0) / counts
