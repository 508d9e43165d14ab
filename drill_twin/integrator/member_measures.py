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

import math

import numpy as np

from drill_twin.numerics.compiled import inline, kernel


@kernel
def measure_members(q, q_rate, q_acceleration, axial_start, bit_row, top_row, finite, bit_u,
                    top_rate, kinetic):
    """
    Fill finite, bit_u (m), top_rate (m/s) and kinetic (J with M = I), each (m,).

    bit_row, top_row: the axial rows of [Phi] at the bit and at the top over the axial block,
    whose columns start at ``axial_start``. A member whose state is not finite gets zeros.
    """
    for i in range(q.shape[0]):
        nan_test, energy, depth, speed = _member(q, q_rate, q_acceleration, i, axial_start,
                                                 bit_row, top_row)
        ok = nan_test == 0.0
        finite[i] = ok
        bit_u[i] = depth if ok else 0.0
        top_rate[i] = speed if ok else 0.0
        kinetic[i] = 0.5 * energy if ok else 0.0


@kernel
def screen_members(q, q_rate, q_acceleration, axial_start, bit_row, top_row, rop, omega, wob,
                   tob, hole_depth_m, bounds, torque_max, lateral, v, w, lateral_max, bad):
    """
    Set bad (m,) where a member breaks a bound of the state guard; return how many do.

    The state guard's decision (:class:`~drill_twin.integrator.guard.StateGuard`) in one pass, with
    an identity mass: state and bit quantities finite, the bit's depth (``bounds[0]`` the
    string's length + the bit's axial displacement) between 0 and hole_depth_m (m,) +
    ``bounds[1]`` (the bit's penetration), |ROP| and the top's axial speed <= bounds[2], |bit
    speed| <= bounds[3], |WOB| <= bounds[4], kinetic energy <= bounds[5], |TOB| <=
    torque_max (1 or m,), and with ``lateral`` every node's radial displacement
    hypot(v, w) <= lateral_max (n_nodes,), v and w (m, n_nodes) the nodes' lateral
    displacements (m).
    """
    nodes = lateral_max.shape[0]
    count = 0
    for i in range(q.shape[0]):
        nan_test, energy, depth, speed = _member(q, q_rate, q_acceleration, i, axial_start,
                                                 bit_row, top_row)
        depth += bounds[0]
        bit = rop[i] + omega[i] + wob[i] + tob[i]
        broken = not (nan_test == 0.0 and bit - bit == 0.0)
        broken = broken or not (depth >= 0.0 and depth <= hole_depth_m[i] + bounds[1])
        broken = broken or not (abs(rop[i]) <= bounds[2] and abs(speed) <= bounds[2])
        broken = broken or not (abs(omega[i]) <= bounds[3] and abs(wob[i]) <= bounds[4])
        broken = broken or not (0.5 * energy <= bounds[5])
        broken = broken or not (abs(tob[i]) <= torque_max[min(i, torque_max.shape[0] - 1)])
        if lateral and not broken:
            for node in range(nodes):
                square = v[i, node] * v[i, node] + w[i, node] * w[i, node]
                limit = lateral_max[node]
                if not square < limit * limit * (1.0 - 1e-12):        # hypot near the bound
                    broken = broken or not (math.hypot(v[i, node], w[i, node]) <= limit)
        bad[i] = broken
        count += broken
    return count


@kernel
def largest_top_speed(q_rate, start, row):
    """
    Return the largest |u_top'| of the members (m/s), nan if one is not finite.

    row (k,): the top's axial row of [Phi] over the columns start ... start + k of q_rate
    (m, n).
    """
    largest = 0.0
    for i in range(q_rate.shape[0]):
        speed = 0.0
        for c in range(row.shape[0]):
            speed += row[c] * q_rate[i, start + c]
        if not speed == speed:
            return np.nan
        largest = max(largest, abs(speed))
    return largest


@inline
def _member(q, q_rate, q_acceleration, i, axial_start, bit_row, top_row):
    """
    Return member i's (nan test, q'.q', bit's axial displacement, top's axial speed).

    The nan test is 0 when q, q' and q'' are finite (x - x is 0 for every finite x, nan
    otherwise).
    """
    nan_test = 0.0
    energy = 0.0
    for j in range(q.shape[1]):
        rate = q_rate[i, j]
        nan_test += (q[i, j] - q[i, j]) + (rate - rate) + (q_acceleration[i, j]
                                                           - q_acceleration[i, j])
        energy += rate * rate
    depth = 0.0
    speed = 0.0
    for c in range(bit_row.shape[0]):
        depth += bit_row[c] * q[i, axial_start + c]
        speed += top_row[c] * q_rate[i, axial_start + c]
    return nan_test, energy, depth, speed
