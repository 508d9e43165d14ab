"""Drilling indicators: stick-slip severity, mechanical specific energy, event counts."""
from __future__ import annotations

import math

import numpy as np


def stick_slip_severity(bit_speed_rad_per_s: np.ndarray, axis: int = -1) -> np.ndarray:
    """
    SSI = (omega_max - omega_min) / (2 omega_mean) over ``axis`` (dimensionless).

    Defined only while the bit turns forwards on average (omega_mean > 0): NaN otherwise
    (a stopped or backward-turning bit has no stick-slip severity; never a substitute number).
    """
    speed = np.asarray(bit_speed_rad_per_s, dtype=float)
    mean = np.mean(speed, axis=axis)
    spread = np.max(speed, axis=axis) - np.min(speed, axis=axis)
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.where(mean > 0, spread / (2.0 * mean), np.nan)


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
    area = bit_area_m2(bit_diameter_m)
    axial = np.mean(np.abs(weight_on_bit_n), axis=axis) / area
    rotary_power = np.mean(np.abs(torque_on_bit_nm) * np.abs(bit_speed_rad_per_s), axis=axis)
    rop = np.mean(rop_m_per_s, axis=axis)
    with np.errstate(divide='ignore', invalid='ignore'):
        rotary = np.where(rop > 0, rotary_power / (area * rop), np.inf)
    return axial + rotary


def describe(values: np.ndarray) -> dict[str, float]:
    """{mean, min, max, std} of a 1-D series."""
    values = np.asarray(values, dtype=float)
    return {'mean': float(np.mean(values)), 'min': float(np.min(values)),
            'max': float(np.max(values)), 'std': float(np.std(values))}
