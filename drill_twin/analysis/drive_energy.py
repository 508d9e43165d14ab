"""
The torsional energy budget of the top drive and the string (docs/DRIVES.md, "The top drive").

For member 0 of a simulator driven by a rig's dynamic top drive, step by step:

    motor work  = change of the drive's kinetic energy + work done on the string's top,
    top work + work of the torsional forces (bit, wall, coupling) = change of the string's
              torsional energy + its damping dissipation,

so  motor work + force work = change of drive energy + change of string energy + dissipation.

The string's torsional energy is kinetic ½ w^T M w (w = Phi_t v_t + psi omega, the physical
rotation rates) plus strain ½ q_t^T K_t q_t (psi^T K = 0: the rigid rotation stores none).
Powers are integrated with the trapezoidal rule, the motor's with the torque of the step
times its mean speed (the drive's equation is backward-Euler: that product is exact).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class EnergyBudget:
    """Accumulated energies (J) since the start of the count."""

    motor_work_j: float = 0.0
    force_work_j: float = 0.0
    dissipation_j: float = 0.0
    drive_energy_change_j: float = 0.0
    string_energy_change_j: float = 0.0

    @property
    def residual_j(self) -> float:
        """Motor work + force work - stored energy changes - dissipation (J): 0 if balanced."""
        return (self.motor_work_j + self.force_work_j - self.drive_energy_change_j
                - self.string_energy_change_j - self.dissipation_j)


class EnergyMeter:
    """
    The budget of ``rig``'s dynamic top drive and its string (module docstring).

    Call ``start()`` once, then ``record()`` after every step (:meth:`Rig.step
    <drill_twin.rig.rig.Rig.step>`). The drive is the rig's when the meter is built.
    """

    def __init__(self, rig):
        self.simulator = rig.simulator
        self.drive = rig.top_drive
        self.string = self.drive.string
        self.budget = EnergyBudget()
        self._last = None

    def _instant(self) -> dict:
        sim, string = self.simulator, self.string
        state, forces = sim.state, sim.last
        c = string.columns
        q, v = state.q[0, c], state.q_rate[0, c]
        omega = state.top_speed_rad_per_s
        kinetic = (0.5 * v @ string.mass @ v + omega * string.mass_driven @ v
                   + 0.5 * string.string_inertia_kg_m2 * omega ** 2)
        strain = 0.5 * q @ string.stiffness @ q
        dissipation = (v @ string.damping @ v + 2.0 * omega * string.damping_driven @ v
                       + string.string_damping_nm_s * omega ** 2)
        force = forces.modal[0, c] @ v + omega * np.sum(forces.full[0, string.theta_x])
        return {'omega': omega, 'string': kinetic + strain, 'drive':
                0.5 * self.drive.inertia_kg_m2 * omega ** 2, 'dissipation_w': dissipation,
                'force_w': force, 'time': state.time_s}

    def start(self) -> None:
        self.budget = EnergyBudget()
        self._last = self._instant()

    def record(self) -> None:
        now, last, budget = self._instant(), self._last, self.budget
        dt = now['time'] - last['time']
        mean_speed = 0.5 * (now['omega'] + last['omega'])
        budget.motor_work_j += self.drive.state.motor_torque_nm * mean_speed * dt
        budget.force_work_j += 0.5 * (now['force_w'] + last['force_w']) * dt
        budget.dissipation_j += 0.5 * (now['dissipation_w'] + last['dissipation_w']) * dt
        budget.drive_energy_change_j += now['drive'] - last['drive']
        budget.string_energy_change_j += now['string'] - last['string']
        self._last = now
