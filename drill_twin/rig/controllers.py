"""
Stick-slip controllers: laws on the top drive's speed set-point.

docs/DRIVES.md, "Stick-slip controllers", gives their stick-slip severity and the linear
stability behind it. All three act on the set-point of the drive's PI speed loop:

- ``stiff``: omega_sp = omega_ref (plain PI speed control).
- ``soft_torque`` (SoftTorque/SoftSpeed): torque feedback band-limited and tuned on the
  string's first torsional mode, omega_sp = omega_ref - HP(T_s) / c, a first-order high-pass
  with its corner at a fraction of the first torsional frequency omega_1 (fixed top) and
  c = k_t / omega_1, k_t the string's torsional stiffness (the top damper that damps a
  pendulum of stiffness k_t at omega_1 best).
- ``impedance`` (the Z-Torque idea): omega_sp = omega_ref - (T_s - <T_s>) / zeta, <T_s> the
  slow mean (first-order low-pass, ``top_drive.mean_torque_time_constant_s``): under the stiff
  PI the top is a damper zeta to torque fluctuations; with zeta = I_p sqrt(rho k_s G), the
  pipe's characteristic impedance, a torsional wave reaching the top is absorbed.

T_s is the torque the string takes at the top (a torque sub's reading). The feedback is
closed within the step: the controller's law is affine in the coming step's top speed,
omega_sp = s_0 + s_1 omega_{n+1}, because T_s of the step is (T_s = T_0 + Z omega_{n+1}, see
:mod:`drill_twin.rig.top_drive`); sampled with one step of delay instead, the loop
gain -Z/zeta of the truncated string (Z > zeta) would make it oscillate at the step rate.
"""
from __future__ import annotations

import math

import numpy as np

from drill_twin.rig.top_drive import characteristic_impedance

CONTROLLERS = ('stiff', 'soft_torque', 'impedance')
"""The controllers' names (``top_drive.controller``)."""


class Stiff:
    """omega_sp = omega_ref."""

    name = 'stiff'

    def law(self, command_rad_per_s, mean_torque_nm, dt, torque_0, slope):
        """Return (s_0, s_1) of the set-point omega_sp = s_0 + s_1 omega_{n+1} (rad/s, -)."""
        return command_rad_per_s, 0.0

    def mean_after(self, mean_torque_nm, string_torque_nm, dt):
        """Return the slow mean of T_s after the step (N m): unused, kept as it is."""
        return mean_torque_nm


class TorqueFeedback:
    """
    Set omega_sp = omega_ref - HP(T_s) / c, HP(T) = T - LP(T).

    LP a first-order low-pass of time constant tau (s); c in N m s/rad. The low-pass's state,
    the slow mean <T_s>, is the drive's (:class:`~drill_twin.rig.top_drive.DynamicState`).
    """

    name = 'torque_feedback'

    def __init__(self, impedance_nm_s_per_rad: float, time_constant_s: float):
        self.impedance = float(impedance_nm_s_per_rad)
        self.time_constant_s = float(time_constant_s)

    def _weight(self, dt):
        return dt / (self.time_constant_s + dt)

    def law(self, command_rad_per_s, mean_torque_nm, dt, torque_0, slope):
        """Return (s_0, s_1) of the set-point omega_sp = s_0 + s_1 omega_{n+1} (rad/s, -)."""
        # T - LP(T) after the step, with LP_{n+1} = LP_n + w (T_{n+1} - LP_n), T = T_0 + Z omega.
        keep = 1.0 - self._weight(dt)
        offset = command_rad_per_s - keep * (torque_0 - mean_torque_nm) / self.impedance
        return offset, -keep * slope / self.impedance

    def mean_after(self, mean_torque_nm, string_torque_nm, dt):
        """Return the slow mean of T_s after a step that ended at ``string_torque_nm`` (N m)."""
        return mean_torque_nm + self._weight(dt) * (string_torque_nm - mean_torque_nm)


class SoftTorque(TorqueFeedback):
    """Torque feedback tuned on the first torsional mode (module docstring)."""

    name = 'soft_torque'


class Impedance(TorqueFeedback):
    """The top as a damper zeta (module docstring)."""

    name = 'impedance'


def torsional_stiffness_nm_per_rad(config) -> float:
    """k_t = 1 / sum(L_i / (k_s G I_p)_i), the string's torsional stiffness (N m/rad)."""
    compliance = 0.0
    for s in config.sections:
        polar = math.pi / 32.0 * (s.outer_diameter_m ** 4 - s.inner_diameter_m ** 4)
        compliance += s.length_m / (s.shear_correction_factor * s.shear_modulus_pa * polar)
    return 1.0 / compliance


def first_torsional_frequency_rad_per_s(system) -> float:
    """Return the lowest elastic torsional frequency of the reduced basis (fixed top), rad/s."""
    basis = system.basis
    torsional = (basis.kind == 'torsional') & ~basis.rigid
    if not np.any(torsional):
        raise ValueError('soft_torque needs a torsional mode in the reduced basis '
                         '(reduced_basis.torsional_modes >= 1)')
    return 2.0 * math.pi * float(np.min(basis.frequency_hz[torsional]))


def make_controller(config, system):
    """Build the controller named by ``config.top_drive.controller``."""
    drive = config.top_drive
    if drive.controller == 'stiff':
        return Stiff()
    if drive.controller == 'soft_torque':
        omega_1 = first_torsional_frequency_rad_per_s(system)
        impedance = (drive.impedance_nm_s_per_rad
                     or torsional_stiffness_nm_per_rad(config) / omega_1)
        return SoftTorque(impedance, 1.0 / (drive.soft_torque_corner_fraction * omega_1))
    impedance = drive.impedance_nm_s_per_rad or characteristic_impedance(config)
    return Impedance(impedance, drive.mean_torque_time_constant_s)
