"""
A torsional wave pulse travelling up the string, and its reflection at the top.

The evidence for the impedance controller (docs/DRIVES.md, "Stick-slip controllers":
"Reflection of a torsional pulse").

A wave going up (towards x = 0) is theta(x, t) = f(x + c t): its angular velocity is
c f'(x + c t) and its twist theta' = f' = theta_dot / c. A Gaussian velocity pulse
theta_dot(x) = A exp(-((x - x0) / w)^2) with that twist is projected on the reduced torsional
basis (mass-orthogonal projection). At a station between the pulse and the top, the upward
pulse passes first and the reflected one after; r = (peak of the reflected pulse) / (peak of
the incident one) of the station's speed about the drive's speed.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.special import erf


def upward_pulse(system, center_m: float, width_m: float, amplitude_rad_per_s: float,
                 wave_speed_m_per_s: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the torsional coordinates and rates of an upward Gaussian pulse (module docstring).

    Each of the torsional block's size, in the reduced basis of ``system``.
    """
    torsion = system.blocks['torsional']
    x = system.model.mesh.node_x_m
    rate = amplitude_rad_per_s * np.exp(-((x - center_m) / width_m) ** 2)
    # theta = (1/c) integral of the rate from the top: the twist is rate / c.
    angle = (amplitude_rad_per_s / wave_speed_m_per_s * width_m * math.sqrt(math.pi) / 2.0
             * (erf((x - center_m) / width_m) - erf(-center_m / width_m)))
    rows = system.permutation[torsion.rows]
    mass = system.model.total_mass[np.ix_(rows, rows)]
    project = torsion.shapes_t @ mass              # mass-normalised modes: q = Phi^T M theta
    return project @ angle, project @ rate


def reflection_coefficient(time_s: np.ndarray, station_speed: np.ndarray,
                           split_s: float) -> float:
    """
    Return the peak of the pulse after ``split_s`` over the peak before it (signed).

    Of a speed series about its start value.
    """
    relative = station_speed - station_speed[0]
    before, after = relative[time_s < split_s], relative[time_s >= split_s]
    incident = before[np.argmax(np.abs(before))]
    reflected = after[np.argmax(np.abs(after))]
    return float(reflected / incident)
