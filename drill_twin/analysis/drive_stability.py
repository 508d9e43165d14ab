"""
Linear torsional stability of steady drilling with the top drive and its controller.

Why a controller can or cannot remove stick-slip (docs/DRIVES.md, "Stick-slip controllers":
the growth rates against WOB per controller).

About steady drilling, with the axial motion quasi-static (constant WOB, as in
:mod:`drill_twin.analysis.linear_stability`), the bit's resisting torque varies with the bit
speed as dT/domega = D (negative: velocity weakening, the source of stick-slip). The
perturbations of the torsional coordinates q, the top speed omega, the PI integral I and the
controller's mean torque m obey the descriptor system (continuous time)

    M q'' + C q' + K q = -m_d omega' - c_d omega - phi_b D (phi_b . q' + omega)
    T_s = m_d . q'' + J_s omega' + c_d . q' + c_s omega + D (phi_b . q' + omega)
    J_d omega' = K_p (omega_sp - omega) + I - T_s,   I' = K_i (omega_sp - omega)
    omega_sp = -(T_s - m) / c,  m' = (T_s - m) / tau    (stiff: 1/c = 0)

and the kinematic drive of the paper holds omega = 0. The largest real part of the
eigenvalues is the growth rate of the least stable motion (1/s).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg as la

from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.rig.controllers import make_controller


def bit_torque_slope_nm_s_per_rad(config, speed_rad_per_s: float,
                                  weight_on_bit_n: float) -> float:
    """
    Return dT/domega of the bit's resisting torque at constant WOB (N m s/rad).

    Steady drilling at (speed, WOB > 0 in compression).
    """
    law = BitRockLaw.from_config(config.bit_rock)
    rop = law.steady_rop(speed_rad_per_s, -weight_on_bit_n)
    _, _, _, jac = law.forces_and_jacobian(np.array([rop]), np.array([speed_rad_per_s]))
    j = jac[0]
    return float(-(j[1, 1] - j[1, 0] * j[0, 1] / j[0, 0]))


def growth_rate_per_s(config, system, drive: str, slope_nm_s_per_rad: float) -> float:
    """
    Return the largest real part of the eigenvalues (1/s).

    With ``drive`` 'kinematic' or a controller name (the dynamic drive of
    ``config.top_drive`` with that controller).
    """
    torsion = system.blocks['torsional']
    c = torsion.columns
    mass, damping, stiffness = (system.mass[c, c], system.damping[c, c],
                                system.stiffness[c, c])
    n = mass.shape[0]
    phi = torsion.shapes[system.bit_node]
    d = slope_nm_s_per_rad
    if drive == 'kinematic':
        a = np.block([[np.zeros((n, n)), np.eye(n)],
                      [-la.solve(mass, stiffness),
                       -la.solve(mass, damping + d * np.outer(phi, phi))]])
        return float(np.max(la.eigvals(a).real))
    settings = dataclasses.replace(config.top_drive, mode='dynamic', controller=drive)
    controller = make_controller(dataclasses.replace(config, top_drive=settings), system)
    theta_x = system.field(1)
    m_d, c_d = system.mass_driven[c], system.damping_driven[c]
    j_s = float(np.sum(system.driven_rows['mass'][theta_x]))
    c_s = float(np.sum(system.driven_rows['damping'][theta_x]))
    kp, ki = settings.proportional_gain_nm_s_per_rad, settings.integral_gain_nm_per_rad
    j_d = settings.inertia_kg_m2
    if drive == 'stiff':
        inverse_c, tau = 0.0, 1.0
    else:
        inverse_c, tau = 1.0 / controller.impedance, controller.time_constant_s
    # x = [q (n), v (n), omega, I, m]; E x' = A x.
    size = 2 * n + 3
    q, v, w, i_, m_ = slice(0, n), slice(n, 2 * n), 2 * n, 2 * n + 1, 2 * n + 2
    e_mat, a_mat = np.zeros((size, size)), np.zeros((size, size))
    e_mat[q, q] = np.eye(n)
    a_mat[q, v] = np.eye(n)
    e_mat[v, v], e_mat[v, w] = mass, m_d
    a_mat[v, q] = -stiffness
    a_mat[v, v] = -damping - d * np.outer(phi, phi)
    a_mat[v, w] = -c_d - d * phi
    # T_s = e_t . x' + a_t . x
    e_t, a_t = np.zeros(size), np.zeros(size)
    e_t[v], e_t[w] = m_d, j_s
    a_t[v], a_t[w] = c_d + d * phi, c_s + d
    # J_d omega' + (1 + K_p / c) T_s = K_p m / c - K_p omega + I
    e_mat[w, w] += j_d
    e_mat[w] += (1 + kp * inverse_c) * e_t
    a_mat[w] -= (1 + kp * inverse_c) * a_t
    a_mat[w, m_] += kp * inverse_c
    a_mat[w, w] -= kp
    a_mat[w, i_] += 1.0
    # I' + (K_i / c) T_s = K_i m / c - K_i omega
    e_mat[i_, i_] = 1.0
    e_mat[i_] += ki * inverse_c * e_t
    a_mat[i_] -= ki * inverse_c * a_t
    a_mat[i_, m_] += ki * inverse_c
    a_mat[i_, w] -= ki
    # m' - T_s / tau = -m / tau
    e_mat[m_, m_] = 1.0
    e_mat[m_] -= e_t / tau
    a_mat[m_] += a_t / tau
    a_mat[m_, m_] -= 1.0 / tau
    values = la.eigvals(a_mat, e_mat)
    return float(np.max(values[np.isfinite(values)].real))
