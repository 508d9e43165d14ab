"""Stick-slip controllers: laws on the top drive's speed set-point (issue 13, docs/DRIVES.md).

Each is sampled once per step (a digital controller: it reads the drive's measurements of the
last step and sets the PI loop's set-point for the next):

- ``stiff``: the set-point is the command (plain PI speed control).
- ``soft_torque``: torque feedback as SoftTorque/SoftSpeed: the set-point is lowered by the
  high-passed motor torque (what a drive measures, from its current) divided by an impedance
  c, omega_sp = omega_ref - HP(T_m) / c; the high-pass corner is a fraction of the string's
  first torsional frequency (fixed top), so the loop acts on the stick-slip mode and leaves
  the mean torque alone.
- ``impedance``: the Z-Torque idea: omega_sp = omega_ref - (T_s - <T_s>) / zeta, with T_s the
  torque the string takes at the top and <T_s> its slow mean (first-order low-pass): under a
  stiff PI the top behaves as a damper zeta to torque fluctuations; with zeta the pipe's
  characteristic impedance I_p sqrt(rho k_s G) a torsional wave arriving at the top is
  absorbed, not reflected.
"""
from __future__ import annotations

import math

import numpy as np

from drill_twin.dynamics.top_drive import characteristic_impedance


class Stiff:
    """omega_sp = omega_ref."""

    name = 'stiff'

    def setpoint(self, command_rad_per_s: float, drive, dt: float) -> float:
        return command_rad_per_s


class SoftTorque:
    """omega_sp = omega_ref - HP(T_m) / c (module docstring).

    Args:
        impedance_nm_s_per_rad: c (N m s/rad).
        corner_rad_per_s: the high-pass corner (rad/s).
    """

    name = 'soft_torque'

    def __init__(self, impedance_nm_s_per_rad: float, corner_rad_per_s: float):
        self.impedance = float(impedance_nm_s_per_rad)
        self.time_constant_s = 1.0 / float(corner_rad_per_s)
        self._last_input = None
        self._output = 0.0

    def setpoint(self, command_rad_per_s: float, drive, dt: float) -> float:
        torque = drive.motor_torque_nm
        if self._last_input is None:
            self._last_input = torque
        weight = self.time_constant_s / (self.time_constant_s + dt)
        self._output = weight * (self._output + torque - self._last_input)
        self._last_input = torque
        return command_rad_per_s - self._output / self.impedance


class Impedance:
    """omega_sp = omega_ref - (T_s - <T_s>) / zeta (module docstring).

    Args:
        impedance_nm_s_per_rad: zeta (N m s/rad).
        mean_time_constant_s: time constant of the mean <T_s> (s).
    """

    name = 'impedance'

    def __init__(self, impedance_nm_s_per_rad: float, mean_time_constant_s: float):
        self.impedance = float(impedance_nm_s_per_rad)
        self.mean_time_constant_s = float(mean_time_constant_s)
        self.mean_torque_nm = None

    def setpoint(self, command_rad_per_s: float, drive, dt: float) -> float:
        torque = drive.string_torque_nm
        if self.mean_torque_nm is None:
            self.mean_torque_nm = torque
        self.mean_torque_nm += dt / (self.mean_time_constant_s + dt) * (torque
                                                                        - self.mean_torque_nm)
        return command_rad_per_s - (torque - self.mean_torque_nm) / self.impedance


def first_torsional_frequency_rad_per_s(system) -> float:
    """The lowest elastic torsional frequency of the reduced basis (fixed top), rad/s."""
    basis = system.basis
    torsional = (basis.kind == 'torsional') & ~basis.rigid
    if not np.any(torsional):
        raise ValueError('soft_torque needs a torsional mode in the reduced basis '
                         '(reduced_basis.torsional_modes >= 1)')
    return 2.0 * math.pi * float(np.min(basis.frequency_hz[torsional]))


def make_controller(config, system):
    """The controller named by ``config.top_drive.controller``."""
    drive = config.top_drive
    impedance = drive.impedance_nm_s_per_rad or characteristic_impedance(config)
    if drive.controller == 'stiff':
        return Stiff()
    if drive.controller == 'soft_torque':
        corner = drive.soft_torque_corner_fraction * first_torsional_frequency_rad_per_s(system)
        return SoftTorque(impedance, corner)
    return Impedance(impedance, drive.mean_torque_time_constant_s)
