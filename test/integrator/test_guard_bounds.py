"""
Each bound of the state guard against its formula from the configuration.

The expected bounds come from guard_formulas (the documented numbers and the string's
sections), never from the guard's attributes: a wrong factor in a bound, or a bound applied
otherwise by the compiled screen or the full check, fails these tests.
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from guard_formulas import (TORQUE_FLOOR_NM, dry_kinetic_energy_max_j, guard_bounds,
                            lateral_max_m)

from drill_twin.config import load_config
from drill_twin.integrator.guard import StateGuard
from drill_twin.integrator.newmark import BatchState
from drill_twin.integrator.simulator import Simulator
from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.rig.rig import Rig

TWIN_STEP = ['integration.time_step_s=0.01']


@pytest.fixture(scope='module')
def config():
    return load_config(None, TWIN_STEP)


def test_each_bound_of_the_guard_is_its_formula_from_the_configuration(config):
    """
    The guard's bounds against the documented formulas, from the string's sections.

    Speeds: 5 block speeds (5 m/s), 5 x max(30 rad/s, top speed); forces: 3 x (WOB_max +
    Z v_block) and 3 x the law's largest torque at that force; the contact penetration
    WOB bound / min(k_ip, k_rock); the lateral bound and the kinetic energy of a dry string
    (its mass and polar inertia are the steel's alone).
    """
    simulator = Simulator(config)
    guard = StateGuard(simulator.system, simulator.law)
    expected = guard_bounds(config, 0.0)
    assert expected['wob'] == pytest.approx(5.343e6, rel=1e-3)            # 3 x (300 kN + Z)
    assert guard.axial_speed_max_m_per_s == pytest.approx(expected['rop'], rel=1e-14)
    assert guard.weight_on_bit_max_n == pytest.approx(expected['wob'], rel=1e-12)
    assert guard.bit_penetration_m == pytest.approx(expected['penetration'], rel=1e-12)
    # (the guard scans 400 speeds, the formula 4001: the largest torque is inside the range)
    assert guard.torque_on_bit_max_nm == pytest.approx(expected['tob'], rel=1e-4)
    for top in (0.0, 12.0, -45.0, 80.0):
        assert guard.rotation_speed_max(top) == pytest.approx(
            guard_bounds(config, top)['bit_speed'], rel=1e-14)
    assert guard.string_length_m == pytest.approx(sum(s.length_m for s in config.sections))
    # A law whose torque is a5 Z alone is largest at the envelope's top speed, 30 rad/s; one
    # that gives no torque has the floor's scale.
    a5_only = load_config(None, TWIN_STEP + ['bit_rock.a4_n_rad=0'])
    e = config.bit_rock.regularization_rad_per_s
    assert StateGuard(simulator.system, BitRockLaw.from_config(a5_only.bit_rock)
                      ).torque_on_bit_max_nm == pytest.approx(
        3.0 * config.bit_rock.a5_n_m * 30.0 / math.hypot(30.0, e), rel=1e-12)
    still = load_config(None, TWIN_STEP + ['bit_rock.a4_n_rad=0', 'bit_rock.a5_n_m=0'])
    assert StateGuard(simulator.system, BitRockLaw.from_config(still.bit_rock)
                      ).torque_on_bit_max_nm == pytest.approx(3.0 * TORQUE_FLOOR_NM, rel=1e-14)
    # The penetration under the softer of the wall's and the rock's springs.
    for rock in ('2.0e7', '5.0e8', 'null'):
        other = load_config(None, TWIN_STEP + ['reduced_basis.lateral_modes=4',
                                               f'bit_rock.contact_stiffness_n_per_m={rock}'])
        built = Simulator(other)
        assert StateGuard(built.system, built.law).bit_penetration_m == pytest.approx(
            guard_bounds(other, 0.0)['penetration'], rel=1e-12)

    dry = load_config(None, TWIN_STEP + ['physics.fluid=false'])
    dry_simulator = Simulator(dry)
    dry_guard = StateGuard(dry_simulator.system, dry_simulator.law)
    np.testing.assert_allclose(dry_guard.lateral_max_m, lateral_max_m(dry), rtol=1e-12)
    for top in (0.0, 45.0):
        assert dry_guard.kinetic_energy_max(top) == pytest.approx(
            dry_kinetic_energy_max_j(dry, top), rel=1e-9)


def test_each_bound_trips_just_above_its_formula_and_not_just_below(config):
    """
    Each quantity at 0.999 and at 1.001 times its bound from the configuration, one per member.

    The bit's ROP, speed, WOB and TOB, the top's axial speed, the kinetic energy (a dry
    string), the depth below the hole's bottom and one node's lateral displacement: the
    compiled screen and the full check each flag exactly the members at 1.001.
    """
    dry = load_config(None, TWIN_STEP + ['physics.fluid=false'])
    simulator = Simulator(dry)
    Rig(simulator).step()
    guard = StateGuard(simulator.system, simulator.law)
    system, one, last = simulator.system, simulator.state, simulator.last
    top = one.top_speed_rad_per_s
    bounds = guard_bounds(dry, top)
    kinds = ('rop_m_per_s', 'bit_speed_rad_per_s', 'weight_on_bit_n', 'torque_on_bit_nm',
             'top_axial_speed', 'kinetic_energy', 'below_the_hole', 'lateral')
    factors = (0.999, 1.001)
    members = len(kinds) * len(factors)
    state = BatchState(one.time_s, np.repeat(one.q, members, axis=0),
                       np.repeat(one.q_rate, members, axis=0),
                       np.repeat(one.q_acceleration, members, axis=0), one.top_angle_rad,
                       top, one.top_acceleration_rad_per_s2, one.hook_load_n,
                       np.repeat(one.hole_u, members))
    bit = {name: np.repeat(getattr(last, name), members).astype(float) for name in kinds[:4]}
    depth = float(simulator.observe().bit_depth_m[0])
    hole = np.full(members, simulator.hole_depth_m[0])
    axial = system.blocks['axial'].columns
    top_row = system.top_axial_row[axial]
    bending = system.blocks['bending_z']
    shape = bending.shapes[:system.n_nodes, 0]
    lateral = lateral_max_m(dry)
    node = int(np.argmax(np.abs(shape) / lateral))                   # the first to touch
    quantity = {'rop_m_per_s': bounds['rop'], 'bit_speed_rad_per_s': bounds['bit_speed'],
                'weight_on_bit_n': bounds['wob'], 'torque_on_bit_nm': bounds['tob']}
    for k in range(members):
        kind, factor = kinds[k // 2], factors[k % 2]
        if kind in quantity:
            bit[kind][k] = -factor * quantity[kind]
        elif kind == 'top_axial_speed':
            state.q_rate[k, axial] = 0.0
            state.q_rate[k, axial.start] = factor * bounds['top_axial_speed'] / top_row[0]
        elif kind == 'kinetic_energy':
            state.q_rate[k] = 0.0                          # one torsional coordinate
            column = system.blocks['torsional'].columns.start
            state.q_rate[k, column] = factor * math.sqrt(
                2 * dry_kinetic_energy_max_j(dry, top) / system.mass[column, column])
        elif kind == 'below_the_hole':
            hole[k] = depth - factor * bounds['penetration']
        else:
            for name in ('bending_y', 'bending_z'):
                state.q[k, system.blocks[name].columns] = 0.0
            state.q[k, bending.columns.start] = factor * lateral[node] / shape[node]
    forces = SimpleNamespace(**bit)
    batch = SimpleNamespace(state=state, last=forces, hole_depth_m=hole)
    screened = guard._screen(batch, state, forces).copy()
    guard._screen = lambda *arguments: None
    reasons = guard.check(batch)
    above = [k for k in range(members) if factors[k % 2] > 1.0]
    assert np.flatnonzero(screened).tolist() == above
    assert sorted(reasons) == above
