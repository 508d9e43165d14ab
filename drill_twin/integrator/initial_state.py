"""
The configured initial motion of a batch, as reduced coordinates (Sect. 2.7).

The rigid axial mode carries the steady ROP of the bit-rock law at the top-drive speed, the
torsional block optionally the steady twist (the steady torque on bit and the drag of the
spinning string in static equilibrium), the bending blocks optionally a lateral deflection
(``initial_conditions``: the first lateral mode, or a half sine over the string or the BHA).
"""
from __future__ import annotations

import math

import numpy as np


def initial_coordinates(system, config, law, members: int, top_speed_rad_per_s: float,
                        lateral: bool = True, steady_twist: bool | None = None):
    """
    Return (q, q_rate), (m, n) each: the configured initial motion of ``members`` members.

    ``system`` the reduced system of ``config``, ``law`` its bit-rock law; ``lateral``: with the
    configured deflection (else none); ``steady_twist``: twisted to carry the steady torque
    (None: as configured).
    """
    if steady_twist is None:
        steady_twist = config.initial_conditions.steady_twist
    n = system.size
    q = np.zeros((members, n))
    q_rate = np.zeros((members, n))
    axial = system.blocks['axial']
    if config.physics.bit_rock and np.any(system.basis.rigid):
        rop = float(law.steady_rop(top_speed_rad_per_s,
                                   system.model.prestress.static_weight_on_bit_n))
        rigid_column = axial.columns.start                 # the rigid mode comes first
        q_rate[:, rigid_column] = rop / axial.shapes[system.bit_node, 0]
    if steady_twist and config.physics.bit_rock:
        q[:, system.blocks['torsional'].columns] = steady_twist_coordinates(
            system, law, top_speed_rad_per_s)
    amplitude = config.initial_conditions.lateral_deflection_m if lateral else 0.0
    bending = system.blocks['bending_y']
    if amplitude > 0 and bending.shapes.shape[1] > 0:
        shape = _lateral_shape(system, config, bending)
        deflection = bending.shapes[:system.n_nodes] @ shape
        q[:, bending.columns] = amplitude / np.max(np.abs(deflection)) * shape
    return q, q_rate


def _lateral_shape(system, config, bending) -> np.ndarray:
    """Return the bending_y coordinates of the configured lateral shape (unscaled)."""
    nodes = system.n_nodes
    if config.initial_conditions.lateral_shape == 'first_lateral_mode':
        shape = np.zeros(bending.shapes.shape[1])
        shape[0] = 1.0
        return shape
    x = system.model.mesh.node_x_m                     # half sine over the string or the BHA
    start = 0.0
    if config.initial_conditions.lateral_shape == 'bha_half_sine':
        start = x[-1] - config.sections[-1].length_m
    length = x[-1] - start
    inside = x >= start - 1e-9
    phase = math.pi * (x - start) / length
    target = np.zeros(2 * nodes)
    target[:nodes] = np.where(inside, np.sin(phase), 0.0)
    target[nodes:] = np.where(inside, (math.pi / length) * np.cos(phase), 0.0)
    mass = system.model.total_mass[np.ix_(system.permutation[bending.rows],
                                          system.permutation[bending.rows])]
    return bending.shapes.T @ (mass @ target)


def steady_twist_coordinates(system, law, top_speed_rad_per_s: float) -> np.ndarray:
    """
    Return the torsional coordinates that carry the steady torque on bit and the drag.

    The drag is that of the spinning string; the coordinates are in static equilibrium
    (K_r q = Phi^T f on the torsional block).
    """
    torsion = system.blocks['torsional']
    wob = system.model.prestress.static_weight_on_bit_n
    torque = float(law.steady_torque(top_speed_rad_per_s, wob))
    load = (torsion.shapes[system.bit_node] * torque
            - system.damping_driven[torsion.columns] * top_speed_rad_per_s)
    stiffness = system.stiffness[torsion.columns, torsion.columns]
    return np.linalg.solve(stiffness, load)
