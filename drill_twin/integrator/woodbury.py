"""
S^-1 of one member with the wall's contact tangents and the imbalance's inertia (Woodbury).

The step's matrix S0 = M + gamma dt C + beta dt^2 K is inverted once; the local laws of a
member add a low-rank term on a few of the local directions U (:class:`LocalOperators`):
S = S0 + U_c D_c U_c^T, and

    S^-1 = S0^-1 - S0^-1 U_c (I + D_c U_c^T S0^-1 U_c)^-1 D_c U_c^T S0^-1.

The wall's tangent k_ip [n n^T + (p/r)(I - n n^T)] at each touching node enters as beta dt^2
times it on the node's (v, w); the imbalance, whose force -A (v'', w'', theta_x'') at its node
is linear in the accelerations, as A = [[0, 0, -m e s], [0, 0, m e c], [-m e s, m e c, m e^2]]
(s, c of the node's spin angle) on its (v, w, theta_x): the Newton step then takes its inertia
whole instead of as a fixed point (which needed three iterations a step).
"""
from __future__ import annotations

import numpy as np

from drill_twin.numerics.compiled import inline, kernel


@inline
def touches(in_contact, i, n_nodes):
    """Whether a node of member i touches the wall (in_contact (m, N))."""
    for node in range(n_nodes):
        if in_contact[i, node]:
            return True
    return False


@kernel
def corrected_response(i, in_contact, tangent, n_nodes, beta_dt2, local, imbalance,
                       displacement_t, y, response):
    """
    Correct y[:, i] = S0^-1 R and response = S0^-1 B to S^-1 of member i; return B^T S^-1 B.

    in_contact (m, N), tangent (m, N, 2, 2): the wall's flags and tangents; beta_dt2: beta
    dt^2 (s^2); local: :class:`LocalOperators`; imbalance: the imbalance's operands
    (:meth:`ImbalanceForce.arguments`), its node's spin angle read from displacement_t
    (D, m); y (n, m), response (n, 2) corrected in place. Returns (2, 2).
    """
    index, d = _local_terms(i, in_contact, tangent, n_nodes, beta_dt2, imbalance,
                            displacement_t)
    local_gram, local_directions, local_response = local.gram, local.directions, local.response
    bit_rows = local.bit_rows
    rank = index.shape[0]
    gram = np.empty((rank, rank))
    for r in range(rank):
        for c in range(rank):
            gram[r, c] = local_gram[index[r], index[c]]
    system = np.eye(rank) + d @ gram
    if not np.all(np.isfinite(system)):
        # A diverged member (an infinite displacement has no direction on the wall): its
        # iterate becomes nan, the step's finiteness check fails it, and the caller retries
        # or restarts it; the other members go on.
        y[:, i] = np.nan
        response[:, :] = np.nan
        return np.full((2, 2), np.nan)
    correction = np.linalg.solve(system, d)                  # (I + D G)^-1 D
    n = y.shape[0]
    directions = np.empty((n, rank))
    responses = np.empty((n, rank))
    for j in range(n):
        for r in range(rank):
            directions[j, r] = local_directions[j, index[r]]
            responses[j, r] = local_response[j, index[r]]
    projected = directions.T @ np.ascontiguousarray(y[:, i])
    change = responses @ (correction @ projected)
    for j in range(n):
        y[j, i] -= change[j]
    bit_gram = np.empty((rank, 2))
    for r in range(rank):
        bit_gram[r, 0] = local_gram[index[r], 0]
        bit_gram[r, 1] = local_gram[index[r], 1]
    response -= responses @ (correction @ bit_gram)
    flexibility = np.empty((2, 2))
    for r in range(2):
        for c in range(2):
            total = 0.0
            for j in range(n):
                total += bit_rows[r, j] * response[j, c]
            flexibility[r, c] = total
    return flexibility


@inline
def _local_terms(i, in_contact, tangent, n_nodes, beta_dt2, imbalance, displacement_t):
    """
    Return (the local directions U_c (rank,) int64, D_c (rank, rank)) of member i.

    Two per touching node (its v and w), three for the imbalance (its node's v, w, theta_x).
    """
    count = 0
    for node in range(n_nodes):
        if in_contact[i, node]:
            count += 1
    extra = 3 if imbalance[0] else 0
    rank = 2 * count + extra
    index = np.empty(rank, dtype=np.int64)
    d = np.zeros((rank, rank))
    k = 0
    for node in range(n_nodes):
        if in_contact[i, node]:
            index[2 * k], index[2 * k + 1] = 2 + node, 2 + n_nodes + node
            for r in range(2):
                for c in range(2):
                    d[2 * k + r, 2 * k + c] = beta_dt2 * tangent[i, node, r, c]
            k += 1
    if extra:
        indices, constants, top_angle = imbalance[1], imbalance[2], imbalance[3]
        node = indices[0]
        angle = top_angle[0] + displacement_t[indices[1], i]
        me, inertia = constants[0], constants[1]
        s, c = np.sin(angle), np.cos(angle)
        first = 2 * count
        index[first], index[first + 1], index[first + 2] = (2 + node, 2 + n_nodes + node,
                                                            2 + 2 * n_nodes)
        d[first, first + 2] = d[first + 2, first] = -me * s
        d[first + 1, first + 2] = d[first + 2, first + 1] = me * c
        d[first + 2, first + 2] = inertia
    return index, d
