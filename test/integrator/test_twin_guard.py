"""
Plausibility: the hook-load range derived from the string, the state guard, honest KPIs.

Bounds are checked against closed forms of the string (weights, masses, drag) and against
configurations and commands that give nonsense without them: a 3 MN hook load on a 1.16 MN
string, bit_rock.a1_m_per_s = 10, bit_rock.a2_m_per_n_s = 1.0.
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from guard_formulas import (BLOCK_SPEED_M_PER_S, TOP_SPEED_MAX_RAD_PER_S, WOB_MAX_N,
                            guard_bounds, impact_weight_on_bit_n, lateral_max_m,
                            law_torque_max_nm)

from drill_twin.config import ConfigError, load_config
from drill_twin.analysis import kpi
from drill_twin.integrator.member_measures import measure_members
from drill_twin.integrator.newmark import BatchState
from drill_twin.integrator.simulator import Simulator
from drill_twin.rig.rig import Rig
from drill_twin.twin.engine import CommandRejected, EnsembleSettings, TwinEngine
from drill_twin.integrator.envelope import StringEnvelope
from drill_twin.integrator.guard import StateGuard

TWIN_STEP = ['integration.time_step_s=0.01']


@pytest.fixture(scope='module')
def config():
    return load_config(None, TWIN_STEP)


def _engine(config, members=0, seed=3):
    with threadpool_limits(limits=1, user_api='blas'):
        return TwinEngine(config, EnsembleSettings(members=members, dispersion=0.01, seed=seed))


def _advance(engine, steps):
    with threadpool_limits(limits=1, user_api='blas'):
        return [engine.advance(1) for _ in range(steps)]


# -- the string's envelope, against closed forms ---------------------------------------------

def test_envelope_of_a_dry_string_is_its_weight_mass_and_drag():
    """
    Without fluid the string's weight is g sum(rho A L).

    Its axial mass is sum(rho A L) and its drag alpha times that mass; the BHA (the collars)
    weighs g rho A_c L_c.
    """
    config = load_config(None, TWIN_STEP + ['physics.fluid=false'])
    envelope = StringEnvelope.of(Simulator(config).system)
    masses = [s.length_m * s.density_kg_per_m3 * math.pi / 4
              * (s.outer_diameter_m ** 2 - s.inner_diameter_m ** 2) for s in config.sections]
    g = config.gravity_m_per_s2
    assert envelope.string_weight_n == pytest.approx(g * sum(masses), rel=1e-9)
    assert envelope.string_mass_kg == pytest.approx(sum(masses), rel=1e-9)
    alpha = config.damping.mass_coefficient_per_s
    assert envelope.axial_drag_n_s_per_m == pytest.approx(alpha * sum(masses), rel=1e-9)
    assert envelope.bha_weight_n == pytest.approx(g * masses[-1], rel=1e-6)
    assert envelope.weight_on_bit_max_n == WOB_MAX_N                        # < the BHA
    assert envelope.hook_load_max_n - envelope.string_weight_n == pytest.approx(
        alpha * sum(masses) * BLOCK_SPEED_M_PER_S, rel=1e-9)
    assert envelope.string_weight_n - envelope.hook_load_min_n == WOB_MAX_N


def test_a_short_bha_caps_the_weight_on_bit():
    """50 m of collars weigh about 140 kN: the neutral point leaves the BHA above that."""
    config = load_config(None, TWIN_STEP + ['physics.fluid=false',
                                            'sections.drill_collar.length_m=50',
                                            'sections.drill_collar.elements=6',
                                            'output.stations_m=[700.0]',
                                            'reduced_basis.lateral_modes=40'])
    envelope = StringEnvelope.of(Simulator(config).system)
    collar = config.sections[-1]
    weight = (config.gravity_m_per_s2 * collar.length_m * collar.density_kg_per_m3 * math.pi / 4
              * (collar.outer_diameter_m ** 2 - collar.inner_diameter_m ** 2))
    assert envelope.weight_on_bit_max_n == pytest.approx(weight, rel=1e-6)


def test_the_weight_is_the_hook_load_of_zero_weight_on_bit(config):
    """
    The stationary WOB is f_c + (H - H_S) (docs/MODEL-CHOICES.md, "Hook load and WOB").

    Zero at H = W = H_S - f_c; the paper's string weighs 1.16 MN as the model counts it (steel
    and fluid).
    """
    simulator = Simulator(config)
    prestress = simulator.system.model.prestress
    envelope = StringEnvelope.of(simulator.system)
    assert prestress.static_weight_on_bit_n + (envelope.string_weight_n
                                               - prestress.hook_load_n) == pytest.approx(0.0)
    assert envelope.string_weight_n == pytest.approx(1.163e6, rel=1e-3)


# -- the command door ------------------------------------------------------------------------

def test_hook_loads_the_model_cannot_represent_are_refused(config):
    engine = _engine(config)
    envelope = engine.envelope
    before = engine.hook_load_command
    with pytest.raises(CommandRejected, match='faster than a block moves') as caught:
        engine.set_hook_load(3.0e6)                 # inside the operator's 0 ... 5 MN
    assert '3000.0 kN exceeds the string\'s weight 1163.3 kN' in str(caught.value)
    with pytest.raises(CommandRejected, match='more than the largest weight on bit 300.0 kN'):
        engine.set_hook_load(envelope.string_weight_n - 310e3)
    assert engine.hook_load_command == before
    events = engine.snapshot().events
    assert [e.kind for e in events] == ['command_rejected'] * 2
    assert all('previous command stays' in e.message for e in events)
    # The edges are accepted: the bit just off the rock, and WOB 300 kN.
    engine.set_hook_load(envelope.hook_load_max_n)
    engine.set_hook_load(envelope.string_weight_n - WOB_MAX_N + 1.0)
    assert engine.rejected_commands == 2 and engine.commands_received == 4


def test_the_highest_hook_load_lifts_the_string_no_faster_than_a_block(config):
    """
    At the largest accepted hook load the string rises at most at the block speed.

    The excess over the weight balanced by the axial drag (terminal speed dH / C = v_block).
    """
    engine = _engine(config)
    envelope = engine.envelope
    engine.set_hook_load(envelope.hook_load_max_n)
    engine.kpi_window_s = 1.0
    snapshots = _advance(engine, 300)
    velocity = np.array([s.observation.bit_axial_velocity_m_per_s[0] for s in snapshots])
    assert velocity[-1] < 0                                   # lifted: rising
    assert np.all(-velocity < BLOCK_SPEED_M_PER_S)
    assert not any(e.kind in ('implausible', 'diverged') for s in snapshots for e in s.events)
    last = snapshots[-1]
    assert last.observation.bit_depth_m[0] < last.observation.hole_depth_m[0]   # off bottom
    assert any(e.kind == 'lift_off' for s in snapshots for e in s.events)
    # Off bottom the hole does not deepen (ROP 0) and no rock is cut: the MSE is not
    # computable (not 0, not a number); the stick-slip severity still is.
    assert last.bit.rop_m_per_s == 0.0
    assert last.mse_pa is None
    assert last.rop_m_per_h is not None and last.rop_m_per_h >= 0
    assert last.stick_slip_severity is not None and last.stick_slip_severity >= 0


# -- the state guard -------------------------------------------------------------------------

def test_a_hook_load_past_the_door_trips_the_guard_and_nothing_implausible_comes_out(config):
    """
    3 MN sent straight to the mean model's rig (as if the door were open).

    The mean model's steps break the speed bounds; each breach is an ERROR event, the mean model
    goes back to its last good state and restarts there; every snapshot stays in the hole at
    plausible speeds (before the guard the bit left the hole upwards at hundreds of m/s). The
    drum's brake (``drawworks.block_speed_max_m_per_s``) would hold the string to 1 m/s: it is
    switched off here, the bare hook force of the paper being what the guard must survive.
    """
    config = load_config(None, TWIN_STEP + ['drawworks.block_speed_max_m_per_s=null'])
    engine = _engine(config)
    bounds = guard_bounds(config, 0.0)
    engine.rig.set_hook_load(3.0e6)
    snapshots = _advance(engine, 100)
    breaches = [e for s in snapshots for e in s.events if e.kind == 'implausible']
    assert breaches and all(e.level == 'error' for e in breaches)
    assert 'the mean model: ' in breaches[0].message and 'beyond' in breaches[0].message
    for s in snapshots:
        hole = float(s.observation.hole_depth_m[0])
        assert hole <= 1600.02                 # the restarts drill about 1 cm in the second
        assert 0 <= s.bit.depth_m <= hole + bounds['penetration']
        assert abs(s.bit.rop_m_per_s) <= bounds['rop']
        assert abs(float(s.observation.hook_velocity_m_per_s[0])) <= bounds['top_axial_speed']
        assert abs(s.bit.speed_rad_per_s) <= bounds['bit_speed']
    health = snapshots[-1].health
    assert health['mean_model_implausible_steps'] == len(breaches) == health['mean_model_resets']
    assert snapshots[-1].step == 100                         # the clock went on


@pytest.mark.parametrize('override, words', [
    ('bit_rock.a1_m_per_s=10', 'ROP -8.712 m/s is beyond +-5 m/s'),
    ('bit_rock.a2_m_per_n_s=1.0', 'ROP 8.718e+04 m/s is beyond +-5 m/s'),
])
def test_a_configuration_implausible_from_the_start_is_refused(override, words):
    """
    The steady state of these bit-rock laws drills at metres or kilometres per second.

    The engine refuses the configuration with one line instead of publishing it.
    """
    config = load_config(None, TWIN_STEP + [override])
    with pytest.raises(ConfigError) as caught:
        TwinEngine(config, EnsembleSettings(members=0))
    message = str(caught.value)
    assert '\n' not in message and 'cannot be integrated' in message and words in message


def test_an_implausible_member_is_restarted_and_the_others_go_on(config):
    """
    A finite but absurd axial speed in one ensemble member (10 m/s on the rigid mode).

    Only that member is put back and restarted (a WARN), the other members and the mean model
    are exactly as in an undisturbed twin.
    """
    disturbed, clean = _engine(config, members=3), _engine(config, members=3)
    _advance(disturbed, 20)
    _advance(clean, 20)
    ensemble = disturbed.ensemble_runner.simulator
    rigid = ensemble.system.blocks['axial'].columns.start
    shape = ensemble.system.blocks['axial'].shapes[0, 0]
    ensemble.state.q_rate[1, rigid] = -10.0 / shape                  # member 2 rising 10 m/s
    snapshots = _advance(disturbed, 3)                  # the ensemble is a tick behind
    snapshot, clean_snapshot = snapshots[-1], _advance(clean, 3)[-1]
    events = [e for s in snapshots for e in s.events if e.kind == 'implausible']
    assert len(events) == 1 and events[0].level == 'warn'
    assert events[0].values['members'] == '2' and 'ensemble members [2]' in events[0].message
    assert 'restarted from a safe state' in events[0].message
    # The bit at the breach, as the step that broke the bound computed it (WOB > 0 compressing).
    assert float(events[0].values['rop_m_per_s']) == pytest.approx(-10.0, rel=0.05)
    assert f"ROP {float(events[0].values['rop_m_per_s']):.4g} m/s)" in events[0].message
    for key in ('weight_on_bit_n', 'torque_on_bit_nm', 'bit_speed_rad_per_s'):
        assert math.isfinite(float(events[0].values[key]))
    state = ensemble.state
    for row in (0, 2):
        np.testing.assert_array_equal(state.q[row], clean.ensemble_runner.simulator.state.q[row])
    assert abs(ensemble.observe().rop_m_per_s[1]) < 0.1
    assert snapshot.bit == clean_snapshot.bit
    assert snapshot.health['ensemble_resets'] == 1 and snapshot.health['mean_model_resets'] == 0


def test_every_bound_of_the_guard_trips(config):
    """
    Each bound on its own, on a converged state of one member.

    The lateral displacement beyond the clearance, the bit below the bottom of the hole, the
    kinetic energy.
    """
    simulator = Simulator(config)
    Rig(simulator).step()
    guard = StateGuard(simulator.system, simulator.law)
    assert guard.check(simulator) == {}
    system = simulator.system
    saved = simulator.state.copy()

    bending = system.blocks['bending_y']
    nodes = system.n_nodes
    deflection = bending.shapes[:nodes] @ saved.q[0, bending.columns]
    mode = np.zeros(bending.columns.stop - bending.columns.start)
    mode[0] = 1.0
    shape = bending.shapes[:nodes] @ mode
    node = int(np.argmax(np.abs(shape)))
    target = 2.0 * guard.lateral_max_m[node]
    simulator.state.q[0, bending.columns.start] += (target - deflection[node]) / shape[node]
    (reason,) = guard.check(simulator).values()
    assert 'lateral displacement' in reason and 'clearance plus contact penetration' in reason

    simulator.state = saved.copy()
    simulator.state.hole_u = simulator.hole_u() - 1.0        # a hole 1 m shallower than the bit
    assert simulator.hole_depth_m[0] < simulator.observe().bit_depth_m[0] - 0.9
    (reason,) = guard.check(simulator).values()
    assert 'below the bottom of the hole' in reason
    simulator.state = saved.copy()

    torsion = system.blocks['torsional'].columns
    simulator.state.q_rate[0, torsion] = 0.0
    simulator.state.q_rate[0, torsion.start] = 1.01 * math.sqrt(
        2 * guard.kinetic_energy_max(simulator.state.top_speed_rad_per_s))
    reasons = guard.check(simulator)
    assert 'exceeds what the hook and the top drive could have supplied' in reasons[0]
    simulator.state = saved.copy()

    # A compressive spike (the rock pushing the bit up: f_bit < 0) reads as a positive WOB.
    wob = guard_bounds(config, 0.0)['wob']
    simulator.last.weight_on_bit_n[0] = -2.0 * wob
    (reason,) = guard.check(simulator).values()
    assert reason == (f'WOB {2.0 * wob:.4g} N (compression > 0) is beyond +-{wob:.4g} N')


def test_the_guards_measures_are_the_states_own():
    """
    The compiled pass (integrator.member_measures) against numpy on a random batch.

    Finite flags (a nan, an inf, a huge finite value), the bit's and top's axial
    displacement and speed over the axial block, 1/2 q'.q'; non-finite members read zero.
    """
    generator = np.random.default_rng(11)
    members, n, start, size = 6, 20, 4, 7
    q, rate, acceleration = (generator.standard_normal((members, n)) for _ in range(3))
    q[1, 3] = np.nan
    rate[2, 17] = np.inf
    acceleration[3, 0] = -np.inf
    q[4, 5] = 1e300                                        # huge, finite
    bit_row, top_row = generator.standard_normal(size), generator.standard_normal(size)
    finite = np.empty(members, dtype=bool)
    bit_u, top_rate, kinetic = np.empty(members), np.empty(members), np.empty(members)
    measure_members(q, rate, acceleration, start, bit_row, top_row, finite, bit_u, top_rate,
                    kinetic)
    expected = (np.isfinite(q).all(axis=1) & np.isfinite(rate).all(axis=1)
                & np.isfinite(acceleration).all(axis=1))
    assert finite.tolist() == expected.tolist() == [True, False, False, False, True, True]
    ok = expected
    axial = slice(start, start + size)
    np.testing.assert_allclose(bit_u[ok], q[ok][:, axial] @ bit_row, rtol=1e-14)
    np.testing.assert_allclose(top_rate[ok], rate[ok][:, axial] @ top_row, rtol=1e-14)
    np.testing.assert_allclose(kinetic[ok], 0.5 * np.sum(rate[ok] ** 2, axis=1), rtol=1e-14)
    assert not np.any(bit_u[~ok]) and not np.any(top_rate[~ok]) and not np.any(kinetic[~ok])


def test_the_compiled_screen_decides_as_the_full_check(config):
    """
    The one-pass screen (member_measures.screen_members) flags exactly the members check words.

    40 copies of a converged state, each with one quantity set at 0.6, 0.9, 1.1 or 1.4 times
    its bound (or not finite): the bit's four quantities, the top's axial speed, the kinetic
    energy, the depth against the hole and the surface, one node's lateral displacement. The
    full check (measure everything, then word the reasons) is run with the screen switched off.
    """
    simulator = Simulator(config)
    Rig(simulator).step()
    guard = StateGuard(simulator.system, simulator.law)
    system, one, last = simulator.system, simulator.state, simulator.last
    members = 40
    state = BatchState(one.time_s, np.repeat(one.q, members, axis=0),
                       np.repeat(one.q_rate, members, axis=0),
                       np.repeat(one.q_acceleration, members, axis=0), one.top_angle_rad,
                       one.top_speed_rad_per_s, one.top_acceleration_rad_per_s2, one.hook_load_n,
                       np.repeat(one.hole_u, members))
    bit = {name: np.repeat(getattr(last, name), members).astype(float)
           for name in ('rop_m_per_s', 'bit_speed_rad_per_s', 'weight_on_bit_n',
                        'torque_on_bit_nm')}
    hole = np.full(members, simulator.hole_depth_m[0])
    top = state.top_speed_rad_per_s
    axial, torsion = system.blocks['axial'].columns, system.blocks['torsional'].columns
    bending = system.blocks['bending_z']
    shape = bending.shapes[:system.n_nodes, 0]
    lateral = lateral_max_m(config)
    node = int(np.argmax(np.abs(shape) / lateral))                   # the first to touch
    expected = guard_bounds(config, top)
    bounds = {'rop_m_per_s': expected['rop'], 'bit_speed_rad_per_s': expected['bit_speed'],
              'weight_on_bit_n': expected['wob'], 'torque_on_bit_nm': expected['tob']}
    top_row = system.top_axial_row[axial]
    for k in range(members):
        factor = (0.6, 0.9, 1.1, 1.4)[k // 10]
        kind = k % 10
        if kind < 4:
            name = list(bounds)[kind]
            bit[name][k] = factor * bounds[name] * (-1) ** (k // 10)
        elif kind == 4:
            state.q_rate[k, axial] = 0.0
            state.q_rate[k, axial.start] = factor * expected['top_axial_speed'] / top_row[0]
        elif kind == 5:
            state.q_rate[k, torsion] = 0.0
            state.q_rate[k, torsion.start] = factor * math.sqrt(
                2 * guard.kinetic_energy_max(top))
        elif kind == 6:
            hole[k] -= (factor - 0.5) * 2 * expected['penetration']
        elif kind == 7:                      # the bit at (1 - factor) x the string's length
            state.q[k, axial.start] -= factor * guard.string_length_m / guard._bit_row[0]
        elif kind == 8:
            for name in ('bending_y', 'bending_z'):          # the first mode of w alone
                state.q[k, system.blocks[name].columns] = 0.0
            state.q[k, bending.columns.start] = factor * lateral[node] / shape[node]
        else:
            [state.q, state.q_rate, state.q_acceleration][k % 3][k, k] = [np.nan, np.inf][k % 2]
    forces = SimpleNamespace(**bit)
    batch = SimpleNamespace(state=state, last=forces, hole_depth_m=hole)
    screened = guard._screen(batch, state, forces).copy()
    guard._screen = lambda *arguments: None
    reasons = guard.check(batch)
    kinds = np.arange(members) % 10
    assert all(screened[kinds == kind].sum() == 2 for kind in range(9))   # 1.1 and 1.4
    assert screened[kinds == 9].all()
    assert sorted(np.flatnonzero(screened).tolist()) == sorted(reasons)


def test_the_screens_speed_bound_follows_the_top_speed(config):
    """
    Above the envelope's top speed the bit-speed bound rises with the top speed, and falls back.

    A bit at 1.2 times the bound of the envelope's speeds passes at twice the envelope's top
    speed and is flagged again back at the envelope's, screened in that order (the screen
    keeps its bounds while the top speed is held).
    """
    from drill_twin.integrator.envelope import ENVELOPE_TOP_DRIVE_SPEED_MAX_RAD_PER_S as top_max
    simulator = Simulator(config)
    Rig(simulator).step()
    guard = StateGuard(simulator.system, simulator.law)
    last = simulator.last
    forces = SimpleNamespace(rop_m_per_s=last.rop_m_per_s.copy(),
                             weight_on_bit_n=last.weight_on_bit_n.copy(),
                             torque_on_bit_nm=last.torque_on_bit_nm.copy(),
                             bit_speed_rad_per_s=np.array([1.2 * guard.rotation_speed_max(0.0)]))
    flagged = []
    for top in (top_max, 2.0 * top_max, 2.0 * top_max, top_max):
        state = simulator.state
        state = BatchState(state.time_s, state.q, state.q_rate, state.q_acceleration,
                           state.top_angle_rad, top, 0.0, state.hook_load_n, state.hole_u)
        batch = SimpleNamespace(state=state, last=forces, hole_depth_m=simulator.hole_depth_m)
        flagged.append(bool(guard._screen(batch, state, forces)[0]))
    assert flagged == [True, False, False, True]


# -- KPIs: finite or nothing -----------------------------------------------------------------

def test_kpis_are_none_until_computable(config):
    engine = _engine(config)
    first = _advance(engine, 1)[0]
    assert (first.stick_slip_severity, first.mse_pa, first.rop_m_per_h) == (None, None, None)
    second = _advance(engine, 1)[0]
    assert all(isinstance(v, float) and math.isfinite(v)
               for v in (second.stick_slip_severity, second.mse_pa, second.rop_m_per_h))


def test_stick_slip_severity_is_undefined_without_forward_rotation():
    """A bit turning backwards on average has no stick-slip severity (NaN, no negative ratio)."""
    assert math.isnan(kpi.stick_slip_severity(np.array([-1.0, -3.0])))
    assert math.isnan(kpi.stick_slip_severity(np.array([0.0, 0.0])))
    assert kpi.stick_slip_severity(np.array([1.0, 3.0])) == pytest.approx(0.5)


def test_a_members_torque_bound_is_that_of_its_own_random_law(config):
    """
    Each member's TOB bound scales with its germ's torsional entry.

    With G = diag(1, g22) (no coupling) the random torque is the mean law's scaled by g22 where
    the bit cuts (the blend weight is 1 - 1e-3 at the smallest ROP of the envelope's points):
    the bound is g22 times the mean law's, and never below it.
    """
    system = Simulator(config).system
    law = Simulator(config).law
    germs = np.array([np.eye(2), np.diag([1.0, 1.3]), np.diag([1.0, 0.7])])
    mean = guard_bounds(config, 0.0)['tob']
    assert np.ndim(StateGuard(system, law).torque_on_bit_max_nm) == 0
    bounds = StateGuard(system, law, germs=germs).torque_on_bit_max_nm
    assert bounds.shape == (3,)
    np.testing.assert_allclose(bounds, [mean, 1.3 * mean, mean], rtol=2e-3)


def test_the_torque_bound_of_coupled_germs_is_each_members_law_evaluated_directly(config):
    """
    The bound of coupled germs is each member's random law's largest |TOB|.

    With G12 != 0, over the envelope's points (Eq. 50), evaluated member by member;
    ``set_germs`` follows germs that change (an ensemble filter estimates them).
    """
    from drill_twin.uncertainty.germ import germs_for_realizations
    simulator = Simulator(config)
    system, law = simulator.system, simulator.law
    germs = germs_for_realizations(0.3, 7, range(12))
    assert np.min(np.abs(germs[:, 0, 1])) > 1e-3
    guard = StateGuard(system, law)
    weight = impact_weight_on_bit_n(config)
    omega = np.linspace(0.01, TOP_SPEED_MAX_RAD_PER_S, 400)             # the guard's points
    rop = np.clip(law.steady_rop(omega, -weight), 0.0, BLOCK_SPEED_M_PER_S)
    force, torque = law.mean(rop, omega)
    mean = np.max(np.abs(torque))
    expected = [max(np.max(np.abs(law.randomised(force, torque, rop, rop, omega,
                                                 np.broadcast_to(g, (400, 2, 2)))[1])), mean)
                for g in germs]
    guard.set_germs(germs)
    np.testing.assert_allclose(guard.torque_on_bit_max_nm, 3.0 * np.array(expected),
                               rtol=1e-12)
    guard.set_germs(None)
    assert guard.torque_on_bit_max_nm == pytest.approx(3.0 * mean, rel=1e-12)


def test_the_torque_the_law_pairs_with_an_accepted_landing_is_accepted():
    """
    A TOB is never refused at a WOB the guard accepts.

    On a rigid rock (``bit_rock.contact_stiffness_n_per_m: null``) the mean model drills at 5.2
    rad/s with 250 kN on the bit; the hook load then rises by 200 kN at once: the string
    springs up, the bit lifts off and lands again, each landing a WOB spike far above the
    envelope's 300 kN (the rock stops the bit within one step). At every step whose WOB is
    inside its bound, the law's TOB is inside the TOB bound; the run reaches torques above
    three times the law's torque at 300 kN, so a TOB bound taken at the envelope's largest WOB
    would reset members whose WOB the guard accepts.
    """
    config = load_config(None, ['integration.time_step_s=0.005',
                                'bit_rock.contact_stiffness_n_per_m=null'])   # rigid rock
    bounds = guard_bounds(config, 0.0)
    with threadpool_limits(limits=1, user_api='blas'):
        simulator = Simulator(config)
        rig = Rig(simulator)
        weight = rig.hook_load_command_n - config.bit_rock.static_weight_on_bit_n
        rig.set_top_drive_speed(5.2)
        rig.set_hook_load(weight - 250e3)
        for _ in range(2000):
            rig.step()
        rig.set_hook_load(weight - 50e3)
        wob, tob = [], []
        for _ in range(1000):
            rig.step()
            wob.append(-float(simulator.last.weight_on_bit_n[0]))
            tob.append(float(simulator.last.torque_on_bit_nm[0]))
    wob, tob = np.array(wob), np.abs(tob)
    accepted = np.abs(wob) <= bounds['wob']
    earlier = 3.0 * law_torque_max_nm(config, WOB_MAX_N)      # the TOB scale at 300 kN
    assert np.max(wob) > WOB_MAX_N                              # landings hit hard
    assert np.max(tob[accepted]) > earlier                       # beyond the envelope's TOB
    assert np.all(tob[accepted] <= bounds['tob'])
