"""
Per-member measures of a batch state in one compiled pass (what the state guard checks).

For every member of a state (q, q', q'') of m members (members first, (m, n)): whether all
three are finite, the bit's and the top's axial displacement and the top's axial speed (rows
of [Phi] over the axial block) and the kinetic energy of the reduced coordinates with an
identity mass, 1/2 q'.q'. One pass over the state instead of a dozen numpy calls: the guard
runs after every step of the mean model and of the ensemble, where those calls cost more than
the arithmetic.
"""
from __future__ import annotations

from drill_twin.dynamics.compiled import kernel


@kernel
def measure_members(q, q_rate, q_acceleration, axial_start, bit_row, top_row, finite, bit_u,
                    top_rate, kinetic):
    """
    Fill finite, bit_u (m), top_rate (m/s) and kinetic (J with M = I), each (m,).

    bit_row, top_row: the axial rows of [Phi] at the bit and at the top over the axial block,
    whose columns start at ``axial_start``. A member whose state is not finite gets zeros.
    """
    members, n = q.shape
    size = bit_row.shape[0]
    for i in range(members):
        nan_test = 0.0                      # x - x is 0 for every finite x, nan otherwise
        energy = 0.0
        for j in range(n):
            rate = q_rate[i, j]
            nan_test += (q[i, j] - q[i, j]) + (rate - rate) + (q_acceleration[i, j]
                                                               - q_acceleration[i, j])
            energy += rate * rate
        depth = 0.0
        speed = 0.0
        for c in range(size):
            depth += bit_row[c] * q[i, axial_start + c]
            speed += top_row[c] * q_rate[i, axial_start + c]
        ok = nan_test == 0.0
        finite[i] = ok
        bit_u[i] = depth if ok else 0.0
        top_rate[i] = speed if ok else 0.0
        kinetic[i] = 0.5 * energy if ok else 0.0
