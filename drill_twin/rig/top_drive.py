"""
The top drive: the paper's imposed speed, a machine under a PI speed loop, or a followed speed.

Three drives set the top-drive speed of the coming step from the speed command
(:class:`TopDriveMode`): :class:`KinematicTopDrive` (the paper's: the speed follows the command
at a bounded acceleration), :class:`DynamicTopDrive` (a rotor of inertia J_d under a PI speed
controller with a torque limit, driving the string's top; docs/DRIVES.md, "The top drive") and
:class:`FollowedTopSpeed` (another model's top speed, imposed step by step: the twin's
ensemble turns at its mean model's). Each keeps its variables in a ``state`` dataclass (what
a rig's checkpoint copies) and reads the simulator without writing into it.

Coupling of the dynamic drive to the string. The string's top rotation is imposed
(``Simulator`` carries it as the rigid rotation psi theta_top). The dynamic drive decides each
step the top speed omega_{n+1} from its own equation of motion

    J_d (omega_{n+1} - omega_n) / dt = T_m(omega_{n+1}) - T_s(omega_{n+1}),

T_m the motor torque (PI, limited) and T_s the torque the string takes at the top (the
``top_torque_nm`` of :class:`~drill_twin.integrator.observation.Observation`), and that speed is
the simulator's input. T_s of the coming step is affine in omega_{n+1}: the string's torsional
block is linear and the simulator's Newmark step (average acceleration, top acceleration
(omega_{n+1} - omega_n) / dt) is replayed here on that block alone
(:mod:`~drill_twin.integrator.newmark_scheme`), for the reference member (member 0), with the
non-linear torsional forces (bit torque, wall rubbing, kinetic coupling) taken from the last
converged step. So

    T_s(omega) = T_0 + Z omega,   Z = dT_s/domega (N m s/rad, includes J_s/dt: the string's
                                   instantaneous inertia seen from the top),

and the drive, the PI and the string's inertia are solved implicitly together (no
added-mass instability however small J_d). The only lag is the change of the non-linear
torsional forces over one step (first order in dt; zero for a linear string, where the
predicted torque equals the simulator's to rounding, test/rig/test_top_drive.py).

Batches: the top speed is shared by all members (the simulator's contract), so the drive
reads the torque of member 0, the twin's reference string; the other members follow.
"""
from __future__ import annotations

import dataclasses
import enum
import math

import numpy as np
import scipy.linalg as la

from drill_twin.config.schema import TopDrive as TopDriveConfig
from drill_twin.integrator import newmark_scheme as newmark


class TopDriveMode(enum.Enum):
    """What sets the top-drive speed of the coming step."""

    KINEMATIC = 'kinematic'
    """The paper's: the speed command followed at a bounded acceleration."""
    DYNAMIC = 'dynamic'
    """A rotor under a PI speed loop and a stick-slip controller, coupled to the string."""
    FOLLOWED = 'followed'
    """Another model's top speed (the twin's ensemble follows its mean model's drive)."""


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


@dataclasses.dataclass(slots=True)
class KinematicState:
    """The kinematic drive's speed (rad/s)."""

    speed_rad_per_s: float

    def copy(self) -> KinematicState:
        return KinematicState(self.speed_rad_per_s)


class KinematicTopDrive:
    """The top-drive speed follows its command at a bounded acceleration (rad/s^2)."""

    mode = TopDriveMode.KINEMATIC

    def __init__(self, speed_rad_per_s: float, max_acceleration_rad_per_s2: float):
        self.max_acceleration = float(max_acceleration_rad_per_s2)
        self.state = KinematicState(float(speed_rad_per_s))

    @property
    def speed_rad_per_s(self) -> float:
        return self.state.speed_rad_per_s

    def advance(self, command_rad_per_s: float, dt: float) -> float:
        """Return the top speed at the end of the coming step (rad/s) under the command."""
        state = self.state
        change = command_rad_per_s - state.speed_rad_per_s
        limit = self.max_acceleration * dt
        state.speed_rad_per_s += min(max(change, -limit), limit)
        return state.speed_rad_per_s


@dataclasses.dataclass(slots=True)
class FollowedState:
    """The followed speed (rad/s): now, and at the end of the coming step."""

    speed_rad_per_s: float
    target_rad_per_s: float

    def copy(self) -> FollowedState:
        return FollowedState(self.speed_rad_per_s, self.target_rad_per_s)


class FollowedTopSpeed:
    """
    The top speed of another model, imposed on this one step by step.

    The online ensemble follows the rig's top drive this way: its members turn at the surface
    speed the mean model's drive gave (kinematic or dynamic, under any controller), as a
    twin's members would turn at the rig's measured surface speed. ``follow(speed)`` before
    each step; ``advance`` returns that speed whatever the command, also when a failed step is
    taken again.
    """

    mode = TopDriveMode.FOLLOWED

    def __init__(self, speed_rad_per_s: float):
        self.state = FollowedState(float(speed_rad_per_s), float(speed_rad_per_s))

    @property
    def speed_rad_per_s(self) -> float:
        return self.state.speed_rad_per_s

    def follow(self, speed_rad_per_s: float) -> None:
        """Set the top speed at the end of the coming step (rad/s)."""
        self.state.target_rad_per_s = float(speed_rad_per_s)

    def advance(self, command_rad_per_s: float, dt: float) -> float:
        self.state.speed_rad_per_s = self.state.target_rad_per_s
        return self.state.speed_rad_per_s


class StringTorque:
    """
    The torque the string takes at its top, measured and predicted one step ahead.

    For member 0 of a :class:`~drill_twin.integrator.simulator.Simulator` (module docstring),
    read from its state, its forces and the operators of its torsional block.
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
        dt = self.dt
        effective = newmark.effective_matrix(self.mass, self.damping, self.stiffness, dt)
        self._solve = (la.lu_factor(effective) if effective.size else None)
        self._slope_rates = -self._apply(self.mass_driven / dt + self.damping_driven)
        self.slope_nm_s_per_rad = float(
            self.string_inertia_kg_m2 / dt + self.string_damping_nm_s
            + (self.mass_driven + newmark.GAMMA * dt * self.damping_driven) @ self._slope_rates)
        """Z = dT_s/domega_{n+1} over one step (N m s/rad)."""

    def _apply(self, vector):
        if self._solve is None:
            return np.zeros(0)
        return la.lu_solve(self._solve, vector)

    def measured(self) -> float:
        """
        T_s at the simulator's current state (N m, > 0 when the drive drives the string).

        The torque balance of the whole string, as ``Simulator.observe`` computes it
        (:meth:`~drill_twin.integrator.simulator.Simulator.string_torque_nm`).
        """
        return self.simulator.string_torque_nm(0)

    def predicted(self) -> tuple[float, float]:
        """(T_0, Z): T_s after the next step is T_0 + Z omega_{n+1} (N m, N m s/rad)."""
        sim = self.simulator
        state, forces = sim.state, sim.last
        c, dt = self.columns, self.dt
        q, v, a = state.q[0, c], state.q_rate[0, c], state.q_acceleration[0, c]
        omega = state.top_speed_rad_per_s
        d_pred = newmark.predicted_displacement(q, v, a, dt)
        v_pred = newmark.predicted_velocity(v, a, dt)
        load = (forces.modal[0, c] - self.damping @ v_pred - self.stiffness @ d_pred
                + self.mass_driven * omega / dt)
        a0 = self._apply(load)
        torque = (-self.string_inertia_kg_m2 * omega / dt + self.mass_driven @ a0
                  + self.damping_driven @ newmark.corrected_velocity(v_pred, a0, dt)
                  - np.sum(forces.full[0, self.theta_x]))
        return float(torque), self.slope_nm_s_per_rad


class PISpeedLoop:
    """
    The drive's speed controller (its gains; the integral is the drive's state).

    T_m = K_p e + I, I' = K_i e, e = omega_sp - omega, |T_m| <= T_max (N m), integrated
    backward-Euler and implicitly with the drive's inertia.

    Anti-windup: while the torque is at its limit the integral is frozen.
    """

    def __init__(self, proportional: float, integral: float):
        self.kp = float(proportional)
        self.ki = float(integral)

    def solve(self, integral_torque_nm: float, limit_nm: float, inertia: float, omega_n: float,
              setpoint: tuple[float, float], dt: float, string_torque_0: float,
              string_slope: float) -> tuple[float, float, bool, float]:
        """
        Return (omega_{n+1}, T_m, saturated, the integral I after the step).

        Solves J (omega - omega_n)/dt = T_m - (T_0 + Z omega) with the set-point
        omega_sp = s_0 + s_1 omega (``setpoint`` = (s_0, s_1): a controller's law may depend
        on the coming step's torque, hence on omega), from the integral I before the step.
        """
        offset, gain_sp = setpoint
        gain = self.kp + self.ki * dt
        omega = ((inertia / dt * omega_n + gain * offset + integral_torque_nm
                  - string_torque_0) / (inertia / dt + gain * (1.0 - gain_sp) + string_slope))
        error = offset + gain_sp * omega - omega
        torque = self.kp * error + integral_torque_nm + self.ki * dt * error
        if abs(torque) <= limit_nm:
            return omega, torque, False, integral_torque_nm + self.ki * dt * error
        torque = math.copysign(limit_nm, torque)
        omega = ((inertia / dt * omega_n + torque - string_torque_0)
                 / (inertia / dt + string_slope))
        return omega, torque, True, integral_torque_nm


@dataclasses.dataclass(slots=True)
class DynamicState:
    """
    The dynamic drive's variables.

    speed (rad/s); string_torque_nm: T_s measured at the start of the last step (N m);
    motor_torque_nm: T_m of the last step; setpoint_rad_per_s: the PI's set-point of the last
    step; saturated: T_m at its limit then; predicted_string_torque_nm: T_0 + Z omega of the
    last step (NaN before the first); integral_torque_nm: the PI's integral I (N m);
    torque_limit_nm: T_max; mean_torque_nm: the controller's slow mean of T_s (None before the
    first step).
    """

    speed_rad_per_s: float
    string_torque_nm: float
    motor_torque_nm: float
    setpoint_rad_per_s: float
    saturated: bool
    predicted_string_torque_nm: float
    integral_torque_nm: float
    torque_limit_nm: float
    mean_torque_nm: float | None = None

    def copy(self) -> DynamicState:
        return DynamicState(self.speed_rad_per_s, self.string_torque_nm, self.motor_torque_nm,
                            self.setpoint_rad_per_s, self.saturated,
                            self.predicted_string_torque_nm, self.integral_torque_nm,
                            self.torque_limit_nm, self.mean_torque_nm)


class DynamicTopDrive:
    """
    The top drive as a machine (module docstring): each step solves its motion with the string's.

    :param simulator: the string it drives (read, never written).
    :param config: the drive (inertia, gains, torque limit).
    :param controller: the stick-slip controller (:mod:`~drill_twin.rig.controllers`).
    :param torque_limit_nm: T_max (None: the configured).

    The PI's integral starts at the string's torque now, the speed at the simulator's (a switch
    from another drive is bumpless).
    """

    mode = TopDriveMode.DYNAMIC

    def __init__(self, simulator, config: TopDriveConfig, controller,
                 torque_limit_nm: float | None = None):
        self.config = config
        self.inertia_kg_m2 = config.inertia_kg_m2
        self.string = StringTorque(simulator)
        self.controller = controller
        self.loop = PISpeedLoop(config.proportional_gain_nm_s_per_rad,
                                config.integral_gain_nm_per_rad)
        speed = float(simulator.state.top_speed_rad_per_s)
        start = self.string.measured()
        self.state = DynamicState(
            speed_rad_per_s=speed, string_torque_nm=start, motor_torque_nm=start,
            setpoint_rad_per_s=speed, saturated=False, predicted_string_torque_nm=math.nan,
            integral_torque_nm=start,
            torque_limit_nm=float(config.torque_limit_nm if torque_limit_nm is None
                                  else torque_limit_nm))

    @property
    def speed_rad_per_s(self) -> float:
        return self.state.speed_rad_per_s

    def advance(self, command_rad_per_s: float, dt: float) -> float:
        """Return the top speed at the end of the coming step (rad/s) under the speed command."""
        if dt != self.string.dt:
            raise ValueError(f'the dynamic top drive steps with dt = {self.string.dt} s, '
                             f'not {dt} s')
        state = self.state
        # The simulator has stepped since the last call: measure the string there first.
        state.string_torque_nm = self.string.measured()
        if state.mean_torque_nm is None:
            state.mean_torque_nm = state.string_torque_nm
        torque_0, slope = self.string.predicted()
        law = self.controller.law(command_rad_per_s, state.mean_torque_nm, dt, torque_0, slope)
        omega, motor, saturated, integral = self.loop.solve(
            state.integral_torque_nm, state.torque_limit_nm, self.inertia_kg_m2,
            state.speed_rad_per_s, law, dt, torque_0, slope)
        state.integral_torque_nm = integral
        state.setpoint_rad_per_s = law[0] + law[1] * omega
        state.motor_torque_nm = motor
        state.saturated = saturated
        state.predicted_string_torque_nm = torque_0 + slope * omega
        state.mean_torque_nm = self.controller.mean_after(
            state.mean_torque_nm, state.predicted_string_torque_nm, dt)
        state.speed_rad_per_s = omega
        return omega
