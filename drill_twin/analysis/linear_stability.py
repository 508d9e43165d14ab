"""
Linear stability of steady drilling.

The axial-torsional reduced model linearised about the steady state the bit-rock law gives at
(Omega, WOB).

About a straight string the linear model does not couple the lateral motion to the axial and
torsional motion, and wall contact is inactive, so the perturbation dq of the axial and
torsional reduced coordinates obeys

    M dq'' + (C - B J B^T) dq' + K dq = 0,

M, C, K the reduced mass, damping and stiffness of those blocks (Eq. 35), B (n, 2) the rows of
[Phi] at the bit's axial and torsional DOFs, and J = d(f_bit, t_bit)/d(ROP, omega) the
bit-rock law's Jacobian at the steady state (the law acts as a non-linear damper on the bit's
velocities). The position of the rigid axial mode (the bit's depth) enters no force and is
left out of the state, so a neutral drift of depth is not counted as an eigenvalue. The
steady state is unstable when the least-stable eigenvalue has a positive real part: its
real part is the growth rate (1/s), its imaginary part the frequency of the growing
oscillation. Neglected: the finite-strain and kinetic-coupling forces linearised about the
steady twist (second order in the twist).

Closed-form limit (test_linear_stability.py): with the axial motion quasi-static (the law's
axial damping 1/(a2 Z^2) ~ 2e7 N s/m makes it settle in milliseconds at constant hook load,
so d f_bit = 0) the bit torque varies with the bit speed along the steady curve at constant
WOB, dT/domega|_WOB = J11 - J10 J01 / J00 with T = -t_bit the resisting torque. A single
mass-normalised torsional mode (pulsation w1, modal damping c1 = alpha + beta w1^2, value
phi_b at the bit) then has s^2 + (c1 + phi_b^2 dT/domega) s + w1^2 = 0: velocity weakening
(dT/domega < 0) destabilises it when -phi_b^2 dT/domega > c1, with growth rate
-(c1 + phi_b^2 dT/domega) / 2.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as la

from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.model.reduced_system import ReducedSystem
from drill_twin.analysis.steady_drilling import SteadyDrilling


@dataclass(frozen=True)
class LinearStability:
    """
    The least-stable eigenvalue of the linearised axial-torsional model.

    growth_rate_per_s: its real part (1/s, > 0 unstable); frequency_hz: |imaginary part| / 2 pi;
    stable: growth_rate_per_s < 0; eigenvalues: all of them, least stable first (1/s).
    """

    growth_rate_per_s: float
    frequency_hz: float
    stable: bool
    eigenvalues: np.ndarray


class AxialTorsionalLinearisation:
    """The linearised axial-torsional model of ``system`` (matrices built once)."""

    def __init__(self, system: ReducedSystem):
        axial, torsion = system.blocks['axial'], system.blocks['torsional']
        columns = np.r_[np.arange(axial.columns.start, axial.columns.stop),
                        np.arange(torsion.columns.start, torsion.columns.stop)]
        pick = np.ix_(columns, columns)
        self.mass = system.mass[pick]
        self.damping = system.damping[pick]
        self.stiffness = system.stiffness[pick]
        n_axial = axial.columns.stop - axial.columns.start
        self.bit_rows = np.zeros((columns.size, 2))                        # B, (n, 2)
        self.bit_rows[:n_axial, 0] = axial.shapes[system.bit_node]
        self.bit_rows[n_axial:, 1] = torsion.shapes[system.bit_node]
        self.elastic = ~system.basis.rigid[system.basis_columns][columns]
        self._mass_inverse = la.inv(self.mass)

    @property
    def size(self) -> int:
        """Number of axial and torsional reduced coordinates."""
        return self.mass.shape[0]

    def state_matrix(self, jacobian: np.ndarray) -> np.ndarray:
        """First-order matrix A of x' = A x, x = (elastic displacements, all rates)."""
        n, elastic = self.size, self.elastic
        n_e = int(np.sum(elastic))
        damping = self.damping - self.bit_rows @ jacobian @ self.bit_rows.T
        a = np.zeros((n_e + n, n_e + n))
        a[:n_e, n_e:] = np.eye(n)[elastic]
        a[n_e:, :n_e] = -self._mass_inverse @ self.stiffness[:, elastic]
        a[n_e:, n_e:] = -self._mass_inverse @ damping
        return a

    def at(self, steady: SteadyDrilling) -> LinearStability:
        """Stability of the steady state ``steady`` (a lifted bit feels no bit-rock force)."""
        jacobian = np.zeros((2, 2)) if steady.lifted else steady.jacobian
        eigenvalues = la.eigvals(self.state_matrix(jacobian))
        eigenvalues = eigenvalues[np.argsort(-eigenvalues.real, kind='stable')]
        least = eigenvalues[0]
        return LinearStability(growth_rate_per_s=float(least.real),
                               frequency_hz=float(abs(least.imag) / (2 * np.pi)),
                               stable=bool(least.real < 0), eigenvalues=eigenvalues)


def stability_grid(system: ReducedSystem, law: BitRockLaw, speeds_rad_per_s,
                   weights_on_bit_n) -> tuple[np.ndarray, np.ndarray]:
    """Growth rate (1/s) and frequency (Hz) over a grid, each shaped (n_wob, n_speed)."""
    linearisation = AxialTorsionalLinearisation(system)
    speeds = np.asarray(speeds_rad_per_s, dtype=float)
    weights = np.asarray(weights_on_bit_n, dtype=float)
    growth = np.empty((weights.size, speeds.size))
    frequency = np.empty_like(growth)
    for i, wob in enumerate(weights):
        for j, speed in enumerate(speeds):
            result = linearisation.at(SteadyDrilling.of(law, speed, wob))
            growth[i, j], frequency[i, j] = result.growth_rate_per_s, result.frequency_hz
    return growth, frequency
