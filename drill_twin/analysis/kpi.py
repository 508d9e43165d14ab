"""Drilling indicators: stick-slip severity, mechanical specific energy, event counts."""
from __future__ import annotations

import math

import numpy as np

from drill_twin.numerics.compiled import kernel


def stick_slip_severity(bit_speed_rad_per_s: np.ndarray, axis: int = -1) -> np.ndarray:
    """
    SSI = (omega_max - omega_min) / (2 omega_mean) over ``axis`` (dimensionless).

    Defined only while the bit turns forwards on average (omega_mean > 0): NaN otherwise
    (a stopped or backward-turning bit has no stick-slip severity; never a substitute number).
    """
    speed = np.asarray(bit_speed_rad_per_s, dtype=float)
    return severity_of(np.mean(speed, axis=axis), np.max(speed, axis=axis),
                       np.min(speed, axis=axis))


def severity_of(mean_speed, largest_speed, smallest_speed):
    """Return the stick-slip severity of the bit speed's mean, largest and smallest (rad/s)."""
    mean_speed = np.asarray(mean_speed, dtype=float)             # numpy's division rules
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.where(mean_speed > 0, (largest_speed - smallest_speed) / (2.0 * mean_speed),
                        np.nan)


def bit_area_m2(bit_diameter_m: float) -> float:
    """Cutting area of the bit (the hole cross-section), m^2."""
    return math.pi * bit_diameter_m ** 2 / 4.0


def mechanical_specific_energy(weight_on_bit_n, torque_on_bit_nm, bit_speed_rad_per_s,
                               rop_m_per_s, bit_diameter_m: float, axis: int = -1):
    """
    Teale's MSE (Pa) over a window: mean|WOB| / A + mean(|TOB| omega) / (A mean(ROP)).

    Energy spent per volume of rock: the axial work term plus the rotary work per unit of
    penetration. inf when the bit does not advance on average (mean ROP <= 0): no rock is
    cut, so the energy per volume is unbounded; callers that publish it treat a non-finite
    MSE as not computable.
    """
    return specific_energy_of(
        np.mean(np.abs(weight_on_bit_n), axis=axis),
        np.mean(np.abs(torque_on_bit_nm) * np.abs(bit_speed_rad_per_s), axis=axis),
        np.mean(rop_m_per_s, axis=axis), bit_diameter_m)


def specific_energy_of(mean_abs_weight_on_bit_n, mean_rotary_power_w, mean_rop_m_per_s,
                       bit_diameter_m: float):
    """Return Teale's MSE (Pa) of the means of |WOB| (N), |TOB| |omega| (W) and ROP (m/s)."""
    area = bit_area_m2(bit_diameter_m)
    mean_rop_m_per_s = np.asarray(mean_rop_m_per_s, dtype=float)   # numpy's division rules
    with np.errstate(divide='ignore', invalid='ignore'):
        rotary = np.where(mean_rop_m_per_s > 0,
                          mean_rotary_power_w / (area * mean_rop_m_per_s), np.inf)
    return mean_abs_weight_on_bit_n / area + rotary


@kernel
def window_means(time_s, since_s, bit_speed_rad_per_s, rop_m_per_s, weight_on_bit_n,
                 torque_on_bit_nm):
    """
    Return what the indicators need of the samples taken at ``time_s`` >= since_s, one pass.

    The arrays: (k,) each, the samples in any order. Returns (count, mean bit speed, largest
    and smallest bit speed (rad/s), mean ROP (m/s), mean |WOB| (N), mean |TOB| |omega| (W)):
    :func:`severity_of` and :func:`specific_energy_of` make the SSI and the MSE of them. The
    twin's KPI window at every tick, where the numpy reductions (a dozen calls over 2001
    samples) cost ten times the arithmetic. A non-finite sample makes the means non-finite,
    as numpy's do.
    """
    count = 0
    speed_sum, rop_sum, weight_sum, power_sum = 0.0, 0.0, 0.0, 0.0
    largest, smallest = -np.inf, np.inf
    for k in range(time_s.shape[0]):
        if time_s[k] >= since_s:
            speed = bit_speed_rad_per_s[k]
            count += 1
            speed_sum += speed
            largest = max(largest, speed)
            smallest = min(smallest, speed)
            rop_sum += rop_m_per_s[k]
            weight_sum += abs(weight_on_bit_n[k])
            power_sum += abs(torque_on_bit_nm[k]) * abs(speed)
    if count == 0:
        return 0, np.nan, np.nan, np.nan, np.nan, np.nan, np.nan
    return (count, speed_sum / count, largest, smallest, rop_sum / count, weight_sum / count,
            power_sum / count)


def describe(values: np.ndarray) -> dict[str, float]:
    """{mean, min, max, std} of a 1-D series."""
    values = np.asarray(values, dtype=float)
    return {'mean': float(np.mean(values)), 'min': float(np.min(values)),
            'max': float(np.max(values)), 'std': float(np.std(values))}
