"""
Steady drilling at a top-drive speed and a weight on bit.

The bit-rock law's state and the reduced coordinates that carry it.

In steady drilling the bit turns with the top drive (omega = Omega), advances at the ROP the
bit-rock law gives at (Omega, f_bit) (Eq. 24, regularised), the string is twisted by the
torque on bit plus the drag of the spinning string, and the hook load balances the weight:
in the stationary mean ``f_bit = f_c + (H - H_S)`` (docs/MODEL-CHOICES.md, "Hook load and
WOB"; the mass-proportional damping's drag on the descending string adds alpha M ROP, a
few newtons, which :func:`under_hook_load` includes). So a weight on bit WOB (> 0 in
compression, f_bit = -WOB) is set by the hook load

    H = W - WOB,   W = H_S - f_c,

W being the string's weight as the model counts it (the hook load that would lift the bit
just off the rock).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as la

from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.model.reduced_system import ReducedSystem


@dataclass(frozen=True)
class SteadyDrilling:
    """
    The bit-rock law at steady drilling (SI units).

    top_speed_rad_per_s: Omega (= the bit speed); weight_on_bit_n: WOB, > 0 in compression;
    rop_m_per_s: the law's ROP at (Omega, -WOB) (negative: the law cannot drill there);
    force_n, torque_nm: f_bit (= -WOB unless lifted) and t_bit; lifted: the law would pull
    on the rock (no contact, zero forces); jacobian: d(f_bit, t_bit)/d(ROP, omega), (2, 2).
    """

    top_speed_rad_per_s: float
    weight_on_bit_n: float
    rop_m_per_s: float
    force_n: float
    torque_nm: float
    lifted: bool
    jacobian: np.ndarray

    @classmethod
    def of(cls, law: BitRockLaw, top_speed_rad_per_s: float,
           weight_on_bit_n: float) -> 'SteadyDrilling':
        """Return the steady state of ``law`` at (Omega, WOB)."""
        omega = float(top_speed_rad_per_s)
        rop = float(law.steady_rop(omega, -float(weight_on_bit_n)))
        force, torque, lifted, jacobian = law.forces_and_jacobian(np.array([rop]),
                                                                  np.array([omega]))
        return cls(top_speed_rad_per_s=omega, weight_on_bit_n=float(weight_on_bit_n),
                   rop_m_per_s=rop, force_n=float(force[0]), torque_nm=float(torque[0]),
                   lifted=bool(lifted[0]), jacobian=jacobian[0].copy())


def string_weight_n(system: ReducedSystem) -> float:
    """W = H_S - f_c: the hook load at which the bit just leaves the rock (N)."""
    prestress = system.model.prestress
    return float(prestress.hook_load_n - prestress.static_weight_on_bit_n)


def hook_load_for(system: ReducedSystem, weight_on_bit_n: float) -> float:
    """Return the hook load (N) that sets a stationary weight on bit WOB (> 0 in compression)."""
    return string_weight_n(system) - float(weight_on_bit_n)


def under_hook_load(system: ReducedSystem, law: BitRockLaw, top_speed_rad_per_s: float,
                    hook_load_n: float, iterations: int = 4) -> SteadyDrilling:
    """
    Steady drilling at the hook load H, with the drag of the descending string.

    The rigid axial mode's balance b_r (f_bit - f_c) = C_rr ROP / b_r + h_r (H - H_S) (b_r, h_r
    its values at the bit and the top) solved with the law's ROP(f_bit) by fixed point (the drag
    changes f_bit by a few newtons, ROP by 1e-7 m/s).
    """
    wob = string_weight_n(system) - float(hook_load_n)
    steady = SteadyDrilling.of(law, top_speed_rad_per_s, wob)
    axial = system.blocks['axial']
    rigid = np.flatnonzero(system.basis.rigid[system.basis_columns][axial.columns])
    if rigid.size == 0:
        return steady
    column = axial.columns.start + rigid[0]
    at_bit = axial.shapes[system.bit_node][rigid[0]]
    prestress = system.model.prestress
    for _ in range(iterations):
        drag = system.damping[column, column] * steady.rop_m_per_s / at_bit
        hook = system.top_axial_row[column] * (hook_load_n - prestress.hook_load_n)
        force = prestress.static_weight_on_bit_n + (drag + hook) / at_bit
        steady = SteadyDrilling.of(law, top_speed_rad_per_s, -force)
    return steady


def steady_coordinates(system: ReducedSystem, steady: SteadyDrilling, hook_load_n: float,
                       q: np.ndarray, q_rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """
    Reduced coordinates (m, n) and rates of steady drilling, from ``q``, ``q_rate``.

    The axial and torsional blocks are replaced (the bending blocks are kept): the rigid
    axial mode moves at the steady ROP, the elastic axial modes carry the static change of
    the bit force and hook load from the prestress, the torsional modes the torque on bit
    and the drag of the string spinning at Omega (K_r q = Phi^T f, rates zero).
    """
    q, q_rate = np.array(q, dtype=float), np.array(q_rate, dtype=float)
    axial, torsion = system.blocks['axial'], system.blocks['torsional']
    bit = system.bit_node
    prestress = system.model.prestress
    rigid = system.basis.rigid[system.basis_columns]
    columns = np.arange(axial.columns.start, axial.columns.stop)
    moving, elastic = columns[rigid[columns]], columns[~rigid[columns]]
    bit_force = 0.0 if steady.lifted else steady.force_n
    axial_load = (axial.shapes[bit][elastic - axial.columns.start]
                  * (bit_force - prestress.static_weight_on_bit_n)
                  - system.top_axial_row[elastic] * (hook_load_n - prestress.hook_load_n))
    q[:, columns] = 0.0
    q_rate[:, columns] = 0.0
    if elastic.size:
        q[:, elastic] = la.solve(system.stiffness[np.ix_(elastic, elastic)], axial_load)
    if moving.size:
        bit_row = axial.shapes[bit][moving - axial.columns.start]
        q_rate[:, moving[0]] = steady.rop_m_per_s / bit_row[0]
    torque = 0.0 if steady.lifted else steady.torque_nm
    q_rate[:, torsion.columns] = 0.0
    if torsion.shapes.shape[1]:
        q[:, torsion.columns] = system.steady_twist(torque, steady.top_speed_rad_per_s)
    return q, q_rate
