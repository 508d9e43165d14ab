"""
The quantities an observation derives from the state, in one compiled pass.

:meth:`Simulator.observe` takes the reduced rows of every observed quantity in one product
(BLAS) and hands the rest here: about thirty small numpy operations before, each costing more
than its arithmetic (an observation after a step of the mean model took about 60 us of CPU,
most of it with the step's operators evicting numpy's working set from the cache).
"""
from __future__ import annotations

from drill_twin.dynamics.bit_rock import maximum
from drill_twin.dynamics.compiled import kernel
from drill_twin.dynamics.newmark_kernel import on_rock

DERIVED = ('depth_m', 'rop_m_per_s', 'angle_rad', 'depth_of_cut_m_per_rad', 'hole_depth_m',
           'top_torque_nm')
"""Rows of :func:`derive`'s ``derived`` array, in order."""


@kernel
def derive(q_rows, rate_rows, acceleration_rows, driven, top_speed, top_acceleration,
           full, torsion_start, torsion_stop, columns, velocity, omega, height, height_rate,
           hole, length_m, e, top_angle, derived, on_bottom):
    """
    Fill ``derived`` (6, m) (rows: DERIVED) and ``on_bottom`` (m,) of an observation.

    q_rows (m, k), rate_rows and acceleration_rows (d, k) for the d <= m detailed members:
    the observer's rows of q, q' and q'' (the driven rotation's rate and acceleration times
    ``driven`` (k,) are added to the latter two, in place); full (m, n_dofs): f_NL, whose
    torsional DOFs are torsion_start:torsion_stop; columns: (mass, damping, bit_u, bit_angle)
    the observer's columns of the torque balance and the bit; velocity, omega: the bit's
    axial velocity and spin (m/s, rad/s), height and height_rate: the rock's surface under the
    bit below the hole's mean bottom (m, m/s), hole: the hole as the bit's axial displacement
    (m), each (m,); length_m: the string's length; e: the law's regularisation (rad/s);
    top_angle (rad). The top torque (row 5) only for the detailed members.
    """
    detailed, k = rate_rows.shape
    mass, damping, bit_u_column, bit_angle_column = columns[0], columns[1], columns[2], columns[3]
    for i in range(detailed):
        for j in range(k):
            rate_rows[i, j] += top_speed * driven[j]
            acceleration_rows[i, j] += top_acceleration * driven[j]
        string = 0.0
        for j in range(torsion_start, torsion_stop):
            string += full[i, j]
        derived[5, i] = (acceleration_rows[i, mass] + rate_rows[i, damping]) - string
    for i in range(q_rows.shape[0]):
        bit_u = q_rows[i, bit_u_column]
        derived[0, i] = length_m + bit_u
        on = on_rock(bit_u, hole[i], height[i])
        on_bottom[i] = on
        rop = maximum(velocity[i] - height_rate[i], 0.0) if on else 0.0
        derived[1, i] = rop
        derived[2, i] = top_angle + q_rows[i, bit_angle_column]
        derived[3, i] = rop * omega[i] / (omega[i] * omega[i] + e * e)
        derived[4, i] = length_m + hole[i]
