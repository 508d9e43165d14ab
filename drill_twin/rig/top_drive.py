"""
The top drive as a machine.

A rotor of inertia J_d under a PI speed controller with a torque limit, driving the string's top
(issue 13; docs/DRIVES.md).

Coupling to the string. The string's top rotation is imposed (``Simulator`` carries it as the
rigid rotation psi theta_top). The dynamic drive decides each step the top speed omega_{n+1}
from its own equation of motion

    J_d (omega_{n+1} - omega_n) / dt = T_m(omega_{n+1}) - T_s(omega_{n+1}),

T_m the motor torque (PI, limited) and T_s the torque the string takes at the top (the
``top_torque_nm`` of :class:`~drill_twin.integrator.simulator.Observation`), and hands that speed
to the simulator as the imposed speed. T_s of the coming step is affine in omega_{n+1}: the
string's torsional block is linear and the simulator's Newmark step (average acceleration,
top acceleration (omega_{n+1} - omega_n) / dt) is replayed here on that block alone, for the
reference member (member 0), with the non-linear torsional forces (bit torque, wall rubbing,
kinetic coupling) taken from the last converged step. So

    T_s(omega) = T_0 + Z omega,   Z = dT_s/domega (N m s/rad, includes J_s/dt: the string's
                                   instantaneous inertia seen from the top),

and the drive, the PI and the string's inertia are solved implicitly together (no
added-mass instability however small J_d). The only lag is the change of the non-linear
torsional forces over one step (first order in dt; zero for a linear string, where the
predicted torque equals the simulator's to rounding, test/test_top_drive.py).

Batches: the top speed is shared by all members (the simulator's contract), so the drive
reads the torque of member 0, the twin's reference string; the other members follow.
"""
from __future__ import annotations

import copy
import math

import numpy as np
import scipy.linalg as la

from drill_twin.config.schema import TopDrive as TopDriveConfig

NEWMARK_BETA = 0.25
NEWMARK_GAMMA = 0.5
"""The simulator's Newmark constants (average acceleration), replayed by the predictor."""


def characteristic_impedance(config) -> float:
    """
    Return zeta = I_p sqrt(rho k_s G) of the top section (N m s/rad).

    The torque per unit of angular velocity a torsional wave carries in the pipe (the model's
    torsional stiffness is k_s G I_p, docs/MODEL-CHOICES.md).
    """
    top = config.sections[0]
    polar = math.pi / 32.0 * (top.outer_diameter_m ** 4 - top.inner_diameter_m ** 4)
    shear = top.shear_correction_factor * top.shear_modulus_pa
    return polar * math.sqrt(top.density_kg_per_m3 * shear)


class StringTorque:
    """
    The torque the string takes at its top, measured and predicted one step ahead.

    For member 0 of a :class:`~drill_twin.integrator.simulator.Simulator` (module docstring).
    """

    def __init__(self, simulator):
        system = simulator.system
        self.simulator = simulator
        self.dt = simulator.dt
        torsion = system.blocks['torsional']
        self.columns = torsion.columns
        self.theta_x = system.field(1)
        c = self.columns
        self.mass = system.mass[c, c]
        self.damping = system.damping[c, c]
        self.stiffness = system.stiffness[c, c]
        self.mass_driven = system.mass_driven[c]
        self.damping_driven = system.damping_driven[c]
        self.string_inertia_kg_m2 = float(np.sum(system.driven_rows['mass'][self.theta_x]))
        """J_s = psi^T M psi, the polar inertia of the whole string (kg m^2)."""
        self.string_damping_nm_s = float(np.sum(system.driven_rows['damping'][self.theta_x]))
        dt, beta, gamma = self.dt, NEWMARK_BETA, NEWMARK_GAMMA
        effective = self.mass + gamma * dt * self.damping + beta * dt * dt * self.stiffness
        self._solve = (la.lu_factor(effective) if effective.size else None)
        self._slope_rates = -self._apply(self.mass_driven / dt + self.damping_driven)
        self.slope_nm_s_per_rad = float(
            self.string_inertia_kg_m2 / dt + self.string_damping_nm_s
            + (self.mass_driven + gamma * dt * self.damping_driven) @ self._slope_rates)
        """Z = dT_s/domega_{n+1} over one step (N m s/rad)."""

    def _apply(self, vector):
        if self._solve is None:
            return np.zeros(0)
        return la.lu_solve(self._solve, vector)

    def measured(self) -> float:
        """
        T_s at the simulator's current state (N m, > 0 when the drive drives the string).

        The torque balance of the whole string, as ``Simulator.observe`` computes it.
        """
        sim = self.simulator
        state, forces = sim.state, sim.last
        c = self.columns
        return float(self.mass_driven @ state.q_acceleration[0, c]
                     + self.damping_driven @ state.q_rate[0, c]
                     + self.string_inertia_kg_m2 * state.top_acceleration_rad_per_s2
                     + self.string_damping_nm_s * state.top_speed_rad_per_s
                     - np.sum(forces.full[0, self.theta_x]))

    def predicted(self) -> tuple[float, float]:
        """(T_0, Z): T_s after the next step is T_0 + Z omega_{n+1} (N m, N m s/rad)."""
        sim = self.simulator
        state, forces = sim.state, sim.last
        c, dt = self.columns, self.dt
        beta, gamma = NEWMARK_BETA, NEWMARK_GAMMA
        q, v, a = state.q[0, c], state.q_rate[0, c], state.q_acceleration[0, c]
        omega = state.top_speed_rad_per_s
        d_pred = q + dt * v + (0.5 - beta) * dt * dt * a
        v_pred = v + (1.0 - gamma) * dt * a
        load = (forces.modal[0, c] - self.damping @ v_pred - self.stiffness @ d_pred
                + self.mass_driven * omega / dt)
        a0 = self._apply(load)
        torque = (-self.string_inertia_kg_m2 * omega / dt + self.mass_driven @ a0
                  + self.damping_driven @ (v_pred + gamma * dt * a0)
                  - np.sum(forces.full[0, self.theta_x]))
        return float(torque), self.slope_nm_s_per_rad


class PISpeedLoop:
    """
    The drive's speed controller.

    T_m = K_p e + I, I' = K_i e, e = omega_sp - omega, |T_m| <= T_max (N m), integrated
    backward-Euler and implicitly with the drive's inertia.

    Anti-windup: while the torque is at its limit the integral is frozen.
    """

    def __init__(self, proportional: float, integral: float, limit_nm: float,
                 integral_torque_nm: float = 0.0):
        self.kp = float(proportional)
        self.ki = float(integral)
        self.limit = float(limit_nm)
        self.integral_torque_nm = float(integral_torque_nm)

    def solve(self, inertia: float, omega_n: float, setpoint: tuple[float, float], dt: float,
              string_torque_0: float, string_slope: float) -> tuple[float, float, bool]:
        """
        Return (omega_{n+1}, T_m, saturated) and update the integral.

        Solves J (omega - omega_n)/dt = T_m - (T_0 + Z omega) with the set-point
        omega_sp = s_0 + s_1 omega (``setpoint`` = (s_0, s_1): a controller's law may depend
        on the coming step's torque, hence on omega).
        """
        offset, gain_sp = setpoint
        gain = self.kp + self.ki * dt
        omega = ((inertia / dt * omega_n + gain * offset + self.integral_torque_nm
                  - string_torque_0) / (inertia / dt + gain * (1.0 - gain_sp) + string_slope))
        error = offset + gain_sp * omega - omega
        torque = self.kp * error + self.integral_torque_nm + self.ki * dt * error
        if abs(torque) <= self.limit:
            self.integral_torque_nm += self.ki * dt * error
            return omega, torque, False
        torque = math.copysign(self.limit, torque)
        omega = ((inertia / dt * omega_n + torque - string_torque_0)
                 / (inertia / dt + string_slope))
        return omega, torque, True


class DynamicTopDrive:
    """
    Stands in for the simulator's kinematic top drive.

    Same ``advance`` and ``speed_rad_per_s``: each step solves the drive's motion coupled to
    the string and returns the top speed the simulator imposes (module docstring).

    ``speed_rad_per_s`` set back to the speed before the last ``advance`` (what the simulator
    does when a step fails) also puts the controller's state back.
    """

    def __init__(self, simulator, config: TopDriveConfig, controller):
        self.simulator = simulator
        self.config = config
        self.inertia_kg_m2 = config.inertia_kg_m2
        self.string = StringTorque(simulator)
        self.controller = controller
        self._speed = float(simulator.state.top_speed_rad_per_s)
        start = self.string.measured()
        self.string_torque_nm = start
        """T_s measured at the last step (N m)."""
        self.motor_torque_nm = start
        """T_m of the last step (N m)."""
        self.setpoint_rad_per_s = self._speed
        self.saturated = False
        self.loop = PISpeedLoop(config.proportional_gain_nm_s_per_rad,
                                config.integral_gain_nm_per_rad, config.torque_limit_nm,
                                integral_torque_nm=start)
        self._undo = None

    @property
    def speed_rad_per_s(self) -> float:
        return self._speed

    @speed_rad_per_s.setter
    def speed_rad_per_s(self, value: float) -> None:
        if self._undo is not None and value == self._undo['_speed']:
            self.__dict__.update(self._undo)             # the step failed: put everything back
        self._speed = float(value)
        self._undo = None

    def advance(self, command_rad_per_s: float, dt: float) -> float:
        """Return the top speed at the end of the coming step (rad/s) under the speed command."""
        if dt != self.string.dt:
            raise ValueError(f'the dynamic top drive steps with dt = {self.string.dt} s, '
                             f'not {dt} s')
        # The simulator has stepped since the last call: measure the string there first.
        self.string_torque_nm = self.string.measured()
        undo = {k: copy.copy(v) for k, v in self.__dict__.items() if k != '_undo'}
        undo['loop'] = copy.copy(self.loop)
        undo['controller'] = copy.deepcopy(self.controller)
        self._undo = undo
        torque_0, slope = self.string.predicted()
        law = self.controller.law(command_rad_per_s, self, dt, torque_0, slope)
        omega, motor, saturated = self.loop.solve(self.inertia_kg_m2, self._speed, law,
                                                  dt, torque_0, slope)
        self.setpoint_rad_per_s = law[0] + law[1] * omega
        self.motor_torque_nm = motor
        self.saturated = saturated
        self.predicted_string_torque_nm = torque_0 + slope * omega
        self.controller.update(self.predicted_string_torque_nm, dt)
        self._speed = omega
        return omega


class FollowedTopSpeed:
    """
    The top speed of another model, imposed on this one step by step.

    The online ensemble follows the rig's top drive this way: its members turn at the surface
    speed the mean model's drive gave (kinematic or dynamic, under any controller), as a
    twin's members would turn at the rig's measured surface speed. ``follow(speed)`` before
    each step; ``advance`` returns that speed whatever the command, also when a failed step is
    taken again.
    """

    def __init__(self, speed_rad_per_s: float):
        self.speed_rad_per_s = float(speed_rad_per_s)
        self.target_rad_per_s = float(speed_rad_per_s)

    def follow(self, speed_rad_per_s: float) -> None:
        """Set the top speed at the end of the coming step (rad/s)."""
        self.target_rad_per_s = float(speed_rad_per_s)

    def advance(self, command_rad_per_s: float, dt: float) -> float:
        self.speed_rad_per_s = self.target_rad_per_s
        return self.speed_rad_per_s


def attach_top_drive(simulator) -> None:
    """
    Replace the simulator's kinematic top drive by the dynamic one if configured.

    Done when the configuration asks for it (``top_drive.mode: dynamic``); nothing otherwise.
    """
    from drill_twin.rig.controllers import make_controller
    config = simulator.config.top_drive
    current = getattr(simulator.top_drive, 'top_drive', simulator.top_drive)
    if config.mode != 'dynamic' or isinstance(current, DynamicTopDrive):
        return                                          # kinematic, or attached already
    simulator.top_drive = DynamicTopDrive(simulator, config,
                                          make_controller(simulator.config, simulator.system))
