"""The mean model in time against invariants, the bit-rock law and refinement."""
from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import config_with, default_raw

from drill_twin.config import load_config
from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.model.forces import Kinematics
from drill_twin.model.kinetic_coupling import kinetic_coupling_energy
from drill_twin.integrator.newmark import NewmarkIntegrator
from drill_twin.model.forces import NonlinearForces
from drill_twin.model.reduced_system import build_reduced_system
from drill_twin.integrator.simulator import SimulationDiverged, Simulator
from drill_twin.fem import strain_energy as se
from drill_twin.modal.reduced_basis import modal_analysis
from drill_twin.simulation.run import run_simulation


def _speed_hz(rad_per_s):
    return rad_per_s / (2 * math.pi)


# -- energy ------------------------------------------------------------------------------------

def _energy(system, q, q_rate):
    """Kinetic (with T_c) plus strain energy (linear part plus the non-linear remainder)."""
    fields = Kinematics.of(system, q, q_rate, np.zeros_like(q), 0.0, 0.0)
    kinetic = 0.5 * np.einsum('mi,ij,mj->m', q_rate, system.mass, q_rate)
    coupling = kinetic_coupling_energy(system, fields)
    linear = 0.5 * np.einsum('mi,ij,mj->m', q, system.stiffness, q)
    u = fields.displacement
    g = (system.strain_operator @ u.T).reshape(se.N_STRAINS, system.n_gauss, -1).transpose(2, 1, 0)
    g_s = system.prestress_strain
    remainder = (se.energy_density(g_s + g, system.section)
                 - se.energy_density(g_s, system.section)
                 - np.einsum('pk,mpk->mp', system.prestress_stress, g)
                 - 0.5 * np.einsum('mpk,pkl,mpl->mp', g, system.prestress_tangent, g))
    nonlinear = np.sum(system.gauss_weight_m * remainder, axis=1)
    return kinetic + coupling + linear + nonlinear, nonlinear + coupling


def _free_string(spin: bool):
    physics = dict(default_raw()['physics'], fluid=False, contact=False, bit_rock=False)
    changes = {'physics': physics, 'operation': {'top_drive_speed_hz': 0.0},
               'damping': {'mass_coefficient_per_s': 0.0, 'stiffness_coefficient_s': 0.0}}
    if spin:
        changes['boundary'] = {'top_torsion': 'free'}
    config = config_with(changes)
    model, _, basis = modal_analysis(config)
    return model, build_reduced_system(model, basis)


def _energy_history(model, system, dt, spin_rad_per_s, steps):
    integrator = NewmarkIntegrator(NonlinearForces(system), dt, 1e-10, 50)
    rng = np.random.default_rng(11)
    q = rng.normal(size=(1, system.size)) * 3.0
    q_rate = rng.normal(size=(1, system.size)) * 3.0
    if spin_rad_per_s:
        torsion = system.blocks['torsional']
        rigid = torsion.columns.start                  # the free string's rigid rotation
        q_rate[:, rigid] = spin_rad_per_s / torsion.shapes[0, 0]
    state = integrator.initial_state(q, q_rate, 0.0, model.prestress.hook_load_n)
    energy, nonlinear = [], []
    for _ in range(steps):
        state, result = integrator.step(state, 0.0, model.prestress.hook_load_n)
        assert result.success
        e, n = _energy(system, state.q, state.q_rate)
        energy.append(e[0])
        nonlinear.append(n[0])
    energy, nonlinear = np.array(energy), np.array(nonlinear)
    return np.ptp(energy) / energy[0], np.ptp(nonlinear) / energy[0]


@pytest.mark.parametrize('spin', [0.0, 5.2])
def test_undamped_free_string_conserves_energy(spin):
    """
    No damping, fluid, contact, bit-rock law or imposed rotation.

    The energy of the prestressed string with its finite-strain and kinetic-coupling forces (a
    freely spinning string for the latter) is conserved up to the trapezoidal rule's
    second-order error, which is small against the swing of the non-linear energy.
    """
    model, system = _free_string(spin > 0)
    drift, swing = _energy_history(model, system, 0.005, spin, 800)
    finer, _ = _energy_history(model, system, 0.0025, spin, 1600)
    assert drift < 1e-3
    assert swing > 50 * drift                              # the non-linear energy really moves
    assert finer / drift == pytest.approx(0.25, rel=0.2)   # second order in the time step


# -- steady state and stationary regime --------------------------------------------------------

def test_steady_drilling_agrees_with_the_bit_rock_law():
    """
    Below the velocity-weakening branch (omega < 2 sqrt(3) e) drilling is steady.

    The bit turns with the top, and ROP, WOB, TOB and the top torque obey the law and torque
    balance.
    """
    omega = 2.0
    config = load_config(None, [f'operation.top_drive_speed_hz={_speed_hz(omega)}',
                                'initial_conditions.steady_twist=true',
                                'initial_conditions.lateral_deflection_m=0'])
    result = run_simulation(config, 20.0)
    law = BitRockLaw.from_config(config.bit_rock)
    wob = config.bit_rock.static_weight_on_bit_n
    last = result.window(10.0)
    ch = result.channels
    np.testing.assert_allclose(ch['bit_speed_rad_per_s'][0, last], omega, rtol=1e-3)
    np.testing.assert_allclose(ch['rop_m_per_s'][0, last], law.steady_rop(omega, wob), rtol=1e-3)
    np.testing.assert_allclose(ch['weight_on_bit_n'][0, last], wob, rtol=1e-3)
    torque = law.steady_torque(omega, wob)
    np.testing.assert_allclose(ch['torque_on_bit_nm'][0, last], torque, rtol=1e-3)
    # Top torque = |TOB| + alpha J Omega (mass-proportional drag of the spinning string).
    mesh = modal_analysis(config)[0].mesh
    polar = np.sum(mesh.density_kg_per_m3 * mesh.polar_inertia_m4 * mesh.length_m)
    drag = config.damping.mass_coefficient_per_s * polar * omega
    np.testing.assert_allclose(ch['top_torque_nm'][0, last], -torque + drag, rtol=1e-3)


@pytest.fixture(scope='module')
def paper_run():
    """Return the run at the paper's operating point, 120 s."""
    return load_config(), run_simulation(load_config(), 120.0)


def _whole_cycles(time, speed, mean):
    """Mask of the window between the first and last upward crossings of ``mean``."""
    up = np.flatnonzero((speed[:-1] < mean) & (speed[1:] >= mean))
    return (time >= time[up[0]]) & (time <= time[up[-1]]), up.size - 1


def test_stationary_bit_speed_equals_top_speed(paper_run):
    config, result = paper_run
    top = config.operation.top_drive_speed_rad_per_s
    speed = result.channels['bit_speed_rad_per_s'][0]
    late = result.time_s >= 40.0
    window, cycles = _whole_cycles(result.time_s[late], speed[late], top)
    assert cycles >= 10                                   # stick-slip cycles of ~4.8 s
    assert np.mean(speed[late][window]) == pytest.approx(top, rel=0.005)
    assert np.ptp(speed[late]) > 4.0                      # and it really oscillates


def test_stationary_weight_on_bit_is_the_hook_load_balance(paper_run):
    """Momentum balance of the rigid axial motion: <f_bit> = f_c + (H - H_S) + alpha M <ROP>."""
    config, result = paper_run
    model = modal_analysis(config)[0]
    mass = np.sum(model.mesh.density_kg_per_m3 * model.mesh.area_m2 * model.mesh.length_m)
    late = result.time_s >= 40.0
    wob = np.mean(result.channels['weight_on_bit_n'][0, late])
    rop = np.mean(result.channels['rop_m_per_s'][0, late])
    expected = (config.bit_rock.static_weight_on_bit_n
                + config.damping.mass_coefficient_per_s * mass * rop)
    assert wob == pytest.approx(expected, abs=20.0)
    assert 1e-3 < rop < 3e-3                               # the paper's 1-3 mm/s


def test_hook_load_sets_the_mean_weight_on_bit():
    base = load_config()
    model = modal_analysis(base)[0]
    slack = 20e3
    config = load_config(None, [f'operation.hook_load_n={model.prestress.hook_load_n - slack}',
                                'initial_conditions.lateral_deflection_m=0'])
    result = run_simulation(config, 60.0)
    late = result.time_s >= 30.0
    wob = np.mean(result.channels['weight_on_bit_n'][0, late])
    assert wob == pytest.approx(base.bit_rock.static_weight_on_bit_n - slack, rel=0.01)


# -- refinement --------------------------------------------------------------------------------

def _bit_speed(overrides, duration=5.0):
    result = run_simulation(load_config(None, overrides), duration, record_interval_s=0.01)
    return result.time_s, result.channels['bit_speed_rad_per_s'][0]


def test_time_step_convergence_is_second_order():
    runs = {dt: _bit_speed([f'integration.time_step_s={dt}'])[1]
            for dt in (0.00125, 0.0025, 0.005, 0.01)}
    differences = [np.abs(runs[2 * dt] - runs[dt]).max() for dt in (0.00125, 0.0025, 0.005)]
    ratios = np.array(differences[1:]) / np.array(differences[:-1])
    np.testing.assert_allclose(ratios, 4.0, rtol=0.25)
    assert differences[1] < 5e-3 * 8.0                     # default step: < 0.5 % of the swing


@pytest.mark.parametrize('key, counts', [('torsional_modes', (2, 4, 8)),
                                         ('axial_modes', (1, 3)),
                                         ('lateral_modes', (40, 158))])
def test_stick_slip_cycle_is_converged_in_the_number_of_modes(key, counts):
    """
    The stationary stick-slip cycle moves by less than 0.01 rad/s as modes are added.

    The bit speed swings about 2.1-8.5 rad/s; measured: 0.003 from 2 to 16 torsional modes.
    Pointwise histories are not compared: the paper's untwisted start is a torque step at
    the bit, a wave that a modal sum resolves slowly, so the first second differs.
    """
    statistics = []
    for count in counts:
        result = run_simulation(load_config(None, [f'reduced_basis.{key}={count}']), 50.0,
                                record_interval_s=0.01)
        speed = result.channels['bit_speed_rad_per_s'][0, result.window(15.0)]
        statistics.append((speed.min(), speed.max(), speed.mean()))
    statistics = np.array(statistics)
    assert np.ptp(statistics[:, 1]) < 0.01 and np.ptp(statistics[:, 0]) < 0.01
    assert np.ptp(statistics[:, 2]) < 0.01
    assert np.all(statistics[:, 1] - statistics[:, 0] > 4.0)


# -- contact and failure ----------------------------------------------------------------------

def test_contact_keeps_the_string_inside_the_clearance():
    """
    Sent at the wall in its first lateral mode, the string bounces off.

    Free amplitude 0.15 m against a clearance of 86.5 mm; the string bounces off with a
    penetration of a fraction of a millimetre.
    """
    config = load_config(None, ['initial_conditions.lateral_deflection_m=0'])
    simulator = Simulator(config)
    system = simulator.system
    bending = system.blocks['bending_y']
    shape = bending.shapes[:system.n_nodes, 0]
    omega = 2 * np.pi * system.basis.frequency_hz[system.basis_columns[bending.columns.start]]
    q_rate = np.zeros((1, system.size))
    q_rate[0, bending.columns.start] = 0.15 / np.abs(shape).max() * omega
    simulator.reset(q_rate=q_rate)
    clearance = (0.3 - 0.127) / 2
    deepest, touched = 0.0, False
    for _ in range(int(12.0 / simulator.dt)):
        simulator.step()
        u = system.physical(simulator.state.q)[0]
        radial = np.hypot(u[system.field(2)], u[system.field(4)])
        deepest = max(deepest, np.max(radial - system.clearance_m))
        touched |= bool(simulator.last.contact.in_contact.any())
    assert touched and simulator.impact_count[0] > 0
    assert 0 < deepest < 1e-3
    assert np.abs(u[system.field(2)]).max() < clearance + 1e-3   # it bounced back


def test_divergence_is_reported_with_its_time():
    simulator = Simulator(load_config(None, ['initial_conditions.lateral_deflection_m=0']))
    for _ in range(10):
        simulator.step()
    before = simulator.state.q.copy()
    with pytest.raises(SimulationDiverged) as info:
        simulator.step(hook_load_n=float('nan'))
    assert info.value.time_s == pytest.approx(11 * simulator.dt)
    assert 't = 0.055' in str(info.value)
    np.testing.assert_array_equal(simulator.state.q, before)   # not silently continued


def test_batch_members_match_single_runs():
    config = load_config()
    single = Simulator(config, members=1)
    batch = Simulator(config, members=3, system=single.system)
    for _ in range(200):
        single.step()
        batch.step()
    for member in range(3):
        np.testing.assert_allclose(batch.state.q[member], single.state.q[0], rtol=1e-10,
                                   atol=1e-14)
