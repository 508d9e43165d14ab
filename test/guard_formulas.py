"""
The state guard's bounds as documented, computed from the configuration alone.

docs/ROS-INTERFACE.md, "The state guard": the numbers the documentation states and the
string's quantities written out from its sections; the guard's own attributes and constants
are never used, so that a test comparing with these sees a wrong factor in the guard.
"""
from __future__ import annotations

import math

import numpy as np

from string_geometry import area_m2, node_masses_and_clearances


BLOCK_SPEED_M_PER_S = 1.0            # a drawworks hoisting a stand; 5 block speeds = 5 m/s
TOP_SPEED_MAX_RAD_PER_S = 30.0       # the envelope's top-drive speed
WOB_MAX_N = 300.0e3                  # the envelope's weight on bit
TORQUE_FLOOR_NM = 1.0e3              # the TOB scale of a law that gives (almost) none


def impact_weight_on_bit_n(config) -> float:
    """
    WOB_max + Z v_block: the envelope's WOB and a landing at block speed on the collars (N).

    Z = A sqrt(E rho) of the bottom section. WOB_max is the envelope's 300 kN when the BHA
    weighs more, even buoyed in the mud.
    """
    collar = config.sections[-1]
    buoyed = (config.gravity_m_per_s2 * area_m2(collar) * collar.length_m
              * (collar.density_kg_per_m3 - config.fluid.density_kg_per_m3))
    assert buoyed > WOB_MAX_N
    impedance = area_m2(collar) * math.sqrt(collar.young_modulus_pa * collar.density_kg_per_m3)
    return WOB_MAX_N + impedance * BLOCK_SPEED_M_PER_S


def law_torque_max_nm(config, force_n: float) -> float:
    """
    Return the largest |t_bit| of Eq. 24-26 (regularised) over 0.01 ... 30 rad/s (N m).

    At the steady ROP of the bit force -``force_n``, capped to [0, v_block]; written out from
    the configuration's constants a1 ... a5 and e.
    """
    law = config.bit_rock
    e = law.regularization_rad_per_s
    omega = np.linspace(0.01, TOP_SPEED_MAX_RAD_PER_S, 4001)
    root = np.sqrt(omega ** 2 + e ** 2)
    z = omega / root
    rop = z ** 2 * (-law.a1_m_per_s + law.a2_m_per_n_s * force_n) + law.a3_m_per_rad * omega * z
    rop = np.clip(rop, 0.0, BLOCK_SPEED_M_PER_S)
    torque = law.a4_n_rad * rop * omega / root ** 2 + law.a5_n_m * omega / root
    return float(np.max(np.abs(torque)))


def guard_bounds(config, top_speed_rad_per_s: float) -> dict[str, float]:
    """Return the guard's bounds as documented, from the configuration (SI)."""
    wob = 3.0 * impact_weight_on_bit_n(config)
    rock = config.bit_rock.contact_stiffness_n_per_m
    stiffness = config.borehole.contact_stiffness_n_per_m
    tob = 3.0 * max(law_torque_max_nm(config, impact_weight_on_bit_n(config)), TORQUE_FLOOR_NM)
    return {'rop': 5.0 * BLOCK_SPEED_M_PER_S, 'top_axial_speed': 5.0 * BLOCK_SPEED_M_PER_S,
            'bit_speed': 5.0 * max(TOP_SPEED_MAX_RAD_PER_S, abs(top_speed_rad_per_s)),
            'wob': wob, 'tob': tob,
            'penetration': wob / (stiffness if rock is None else min(stiffness, rock))}


def dry_kinetic_energy_max_j(config, top_speed_rad_per_s: float) -> float:
    """
    1/2 (M v^2 + J w^2 + M (c w)^2) of a dry string at the speed bounds (J).

    M the steel's mass, J its polar inertia sum(rho I_p L), c the largest clearance, v = 5 m/s
    and w the bit-speed bound.
    """
    mass = sum(s.density_kg_per_m3 * area_m2(s) * s.length_m for s in config.sections)
    polar = sum(s.density_kg_per_m3 * math.pi / 32
                * (s.outer_diameter_m ** 4 - s.inner_diameter_m ** 4) * s.length_m
                for s in config.sections)
    clearance = np.max(node_masses_and_clearances(config)[1])
    omega = 5.0 * max(TOP_SPEED_MAX_RAD_PER_S, abs(top_speed_rad_per_s))
    return 0.5 * (mass * (5.0 * BLOCK_SPEED_M_PER_S) ** 2 + polar * omega ** 2
                  + mass * (clearance * omega) ** 2)


def lateral_max_m(config) -> np.ndarray:
    """Each node's clearance plus 10 m c w^2 / k_ip of the heaviest whirling node (m)."""
    mass, clearance = node_masses_and_clearances(config)
    whirl = np.max(mass * np.maximum(clearance, 0.0) * TOP_SPEED_MAX_RAD_PER_S ** 2)
    return clearance + 10.0 * whirl / config.borehole.contact_stiffness_n_per_m
