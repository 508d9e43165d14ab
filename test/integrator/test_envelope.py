"""
The model never diverges in the driller's envelope (docs/ENVELOPE.md).

The envelope: top-drive speed 0 ... 30 rad/s (0: stopped with the bit on bottom, then
restarted), hook load from the whole string's weight (bit lifted) down to WOB 300 kN, step
changes of either at any instant, germs of dispersion up to 0.3, the twin's 10 ms step and the
offline 5 ms step. First the bit's 2x2 equation alone (it cannot fail), then the sub-step
retries, then runs through the envelope (scripted, and random with hypothesis).

The runs use the paper's string with 20 lateral modes instead of 158 (the bit equation and the
wall contact are the same; the test stays short).
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from string_geometry import node_masses_and_clearances

from drill_twin.config import load_config
from drill_twin.model.bit_equation import solve_bit_equation
from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.integrator.newmark import StepResult
from drill_twin.model.reduced_system import build_reduced_system
from drill_twin.integrator.simulator import SUBSTEP_LEVELS, SimulationDiverged, Simulator
from drill_twin.modal.reduced_basis import modal_analysis
from drill_twin.rig.rig import Rig
from drill_twin.uncertainty.germ import sample_germ

settings.register_profile('envelope', derandomize=True, deadline=None, max_examples=12,
                          database=None, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow])
PENETRATION_M = 1e-3
"""How far past the clearance a node may be pushed by k_ip (test_dynamics_model: < 1 mm)."""


@pytest.fixture(scope='module')
def law():
    return BitRockLaw.from_config(load_config().bit_rock)


# -- the bit's equation ------------------------------------------------------------------------

def _random_problems(rng, m):
    c = np.column_stack([np.full(m, 4.3e-8), np.full(m, 6e-6)]) * rng.uniform(0.1, 4, (m, 1))
    b = np.column_stack([rng.normal(0, 0.02, m), rng.normal(2, 10, m)])
    rho = np.maximum(0.0, rng.normal(0, 0.01, m))
    return b, c, rho


@pytest.mark.parametrize('delta', [0.0, 0.1, 0.3])
def test_bit_equation_is_solved_everywhere(law, delta):
    """
    Random right-hand sides over lift-off, landing, rest, backward rotation and cutting.

    Every member gets a finite solution of both equations, on the law's graph.
    """
    rng = np.random.default_rng(3)
    m = 3000
    b, c, rho = _random_problems(rng, m)
    germ = sample_germ(delta, rng, m) if delta else None
    rop, omega, f1, f2, lifted, on_bottom, cut = solve_bit_equation(law, b, c, rho, germ,
                                                                    omega_guess=b[:, 1])
    assert np.all(np.isfinite(rop) & np.isfinite(omega))
    np.testing.assert_allclose(rop, b[:, 0] + c[:, 0] * f1, rtol=0, atol=1e-12)
    assert np.all(np.abs(omega - b[:, 1] - c[:, 1] * f2) <= 1e-11 * (1 + np.abs(omega)))
    assert np.all(f1 <= 0)
    assert np.all(rop[~on_bottom] <= np.maximum(rho, law.cutting_rate(0.0, omega))[~on_bottom]
                  + 1e-15)
    assert np.all(f1[~on_bottom] == 0) and np.all(f2[~on_bottom] == 0)
    assert np.all(rop[on_bottom] >= rho[on_bottom] - 1e-15)        # never below the bottom
    # Every kind of point occurs.
    assert (~on_bottom).sum() > 100 and (on_bottom & (cut > rho)).sum() > 100
    assert (on_bottom & (omega < 0)).sum() > 100 and (on_bottom & (cut <= rho)).sum() > 100
    if germ is None:
        cutting = on_bottom & (cut > rho) & (omega > 0.1) & (f1 < law.fade_force(omega))
        force, torque = law.mean(rop[cutting], omega[cutting])     # Eq. 25-26 itself
        np.testing.assert_allclose(force, f1[cutting], rtol=1e-9)
        np.testing.assert_allclose(torque, f2[cutting], rtol=1e-9)


def test_backward_rotation_is_resisted(law):
    """
    The regularised law as written for omega < 0.

    The cutting rate is even in omega (R ~ omega^2 near 0), the torque odd and opposed to the
    rotation.
    """
    omega = np.array([-3.0, -0.4, -1e-6, 0.0])
    force = np.full(4, -2e5)
    np.testing.assert_allclose(law.cutting_rate(force, omega), law.cutting_rate(force, -omega),
                               rtol=1e-14)
    torque = law.torque_of_force(force, omega)
    assert np.all(torque[:3] > 0) and torque[3] == 0
    np.testing.assert_allclose(torque, -law.torque_of_force(force, -omega), rtol=1e-14)
    small = np.array([1e-3, 1e-4])
    ratio = law.cutting_rate(np.full(2, -2e5), small) / small ** 2
    assert ratio[1] == pytest.approx(ratio[0], rel=1e-2)


def test_torque_is_continuous_at_lift_off_and_at_the_threshold(law):
    for omega in (0.5, 5.2, 15.0, 30.0):
        threshold = law.threshold_force(omega)
        near_zero = law.torque_of_force(np.array([-1e-6]), np.array([omega]))[0]
        assert abs(near_zero) < 1e-6 * law.a5
        if threshold < 0:
            f = np.array([threshold * (1 + 1e-9), threshold * (1 - 1e-9)])
            t = law.torque_of_force(f, np.full(2, omega))
            assert abs(t[0] - t[1]) < 1e-6 * law.a5
            # Cutting branch: Eq. 26 at the law's own ROP.
            wob = np.array([threshold - 5e4])
            rop = law.cutting_rate(wob, np.array([omega]))
            assert law.torque_of_force(wob, np.array([omega]))[0] == pytest.approx(
                law.mean(rop, np.array([omega]))[1][0], rel=1e-12)


def test_random_law_is_continuous_at_zero_speed(law):
    """
    Along the graph the random forces go to the mean ones as omega -> 0+.

    The graph is ROP = R(f, omega); the blend is in R (the previous blend in ROP left
    G12 sqrt(f t ROP / omega) unbounded).
    """
    germ = np.array([[[0.8, -0.25], [-0.25, 1.2]]])
    force = np.array([-1.5e5])
    for omega in (1e-2, 1e-3, 1e-4):
        w = np.array([omega])
        cut = law.cutting_rate(force, w)
        torque = law.torque_of_force(force, w, cut)
        f1, f2 = law.randomised(force, torque, cut, cut, w, germ)
        assert abs(f1[0] - force[0]) < 1e3 * omega * abs(force[0])
        assert abs(f2[0] - torque[0]) <= 1e3 * omega * abs(torque[0]) + 1e-12


# -- sub-step retries ------------------------------------------------------------------------

@pytest.fixture(scope='module')
def system():
    config = load_config(None, ['reduced_basis.lateral_modes=20'])
    model, _, basis = modal_analysis(config)
    return config, build_reduced_system(model, basis)


def _failing(step, member):
    """Return a full-dt step that reports member ``member`` as failed."""
    def wrapped(state, speed, hook):
        new, result = step(state, speed, hook)
        converged = result.converged.copy()
        converged[member] = False
        return new, StepResult(False, converged, result.finite, result.iterations,
                               result.error, 'made to fail', result.forces)
    return wrapped


def test_a_failed_step_is_retried_on_sub_steps(system):
    config, reduced = system
    reference = Simulator(config, members=3, system=reduced)
    simulator = Simulator(config, members=3, system=reduced)
    for _ in range(20):
        reference.step()
        simulator.step()
    simulator.integrator.step = _failing(simulator.integrator.step, 1)
    before = simulator.state.q.copy()
    result = simulator.step()
    reference.step()
    assert result.success and result.retries.tolist() == [0, 2, 0]   # two half steps
    assert simulator.retries == 1 and simulator.substeps == 2
    assert simulator.time_s == pytest.approx(reference.time_s)
    np.testing.assert_array_equal(simulator.state.q[[0, 2]], reference.state.q[[0, 2]])
    # Member 1 moved on by dt on two half steps: second-order close to the full step.
    change = np.abs(reference.state.q[1] - before[1]).max()
    assert np.abs(simulator.state.q[1] - reference.state.q[1]).max() < 1e-3 * change
    assert np.all(np.isfinite(simulator.observe().weight_on_bit_n))


def test_only_a_member_that_fails_on_dt_over_16_raises(system):
    config, reduced = system
    simulator = Simulator(config, members=2, system=reduced)
    simulator.step()
    simulator.integrator.step = _failing(simulator.integrator.step, 0)
    for level in range(1, SUBSTEP_LEVELS + 1):                     # every sub-step fails too
        integrator = simulator.repair._substep_integrator(level, 0)
        integrator.step = _failing(integrator.step, 0)
    before = simulator.state.q.copy()
    with pytest.raises(SimulationDiverged) as info:
        simulator.step()
    assert info.value.members == (0,)
    assert info.value.time_s == pytest.approx(2 * simulator.dt)
    np.testing.assert_array_equal(simulator.state.q, before)       # nothing kept
    # dt/2 fails, dt/4 fails, dt/8 fails, dt/16 fails: four attempts.
    assert simulator.substeps == SUBSTEP_LEVELS and simulator.retries == 1


# -- runs through the envelope ---------------------------------------------------------------

def _weight(simulator):
    """Return the string's weight as the model counts it: the hook load with zero WOB (N)."""
    return (simulator.system.model.prestress.hook_load_n
            - simulator.config.bit_rock.static_weight_on_bit_n)


def _wob_hook(simulator, wob_n):
    """Return the hook load that gives a static weight on bit of ``wob_n`` (N, > 0)."""
    return _weight(simulator) - wob_n


def _germs(delta, members, seed):
    """Return the mean model first, then germs of dispersion delta, the largest |G12| included."""
    rng = np.random.default_rng(seed)
    pool = sample_germ(delta, rng, 200)
    order = np.argsort(-np.abs(pool[:, 0, 1]))
    germs = np.concatenate([np.eye(2)[None], pool[order[:members - 1]]])
    return germs


class EnvelopeRun:
    """Steps a batch under a command sequence and checks every observation."""

    def __init__(self, simulator: Simulator):
        self.sim = simulator
        self.rig = Rig(simulator)
        self.clearance = node_masses_and_clearances(simulator.config)[1]
        self.hole = simulator.observe(detailed=0).hole_depth_m.copy()
        self.lifted = np.zeros(simulator.members, dtype=bool)
        self.landed = np.zeros(simulator.members, dtype=bool)
        self.steps = 0

    def hold(self, seconds, speed=None, hook=None):
        if speed is not None:
            self.rig.set_top_drive_speed(speed)
        if hook is not None:
            self.rig.set_hook_load(hook)
        for _ in range(int(round(seconds / self.sim.dt))):
            self.rig.step()                                       # raises if it diverges
            self.check()

    def check(self):
        sim = self.sim
        self.steps += 1
        o = sim.observe(detailed=None if self.steps % 10 == 0 else 0)   # stations: 1 in 10
        for name, value in vars(o).items():
            if isinstance(value, np.ndarray) or isinstance(value, float):
                assert np.all(np.isfinite(value)), name
        u = sim.system.physical(sim.state.q)
        radial = np.hypot(u[:, sim.system.field(2)], u[:, sim.system.field(4)])
        assert np.all(radial <= self.clearance + PENETRATION_M)
        assert np.all(o.hole_depth_m >= self.hole)                 # never shallower
        # The bit presses the rock under it (a spring k) by -WOB / k.
        stiffness = sim.config.bit_rock.contact_stiffness_n_per_m
        pressed = np.maximum(-o.weight_on_bit_n, 0.0) / stiffness
        assert np.all(o.bit_depth_m <= o.hole_depth_m + pressed + 1e-6)
        self.hole = o.hole_depth_m.copy()
        self.lifted |= ~o.on_bottom
        self.landed |= o.landings_so_far > 0


@pytest.mark.parametrize('dt', [0.01, 0.005])
def test_scripted_sweep_of_the_envelope(system, dt):
    """
    No step fails over a tour of drilling, backward rotation, restart, lift-off, set-down.

    Drill at the paper's point, then at 30 rad/s with WOB 300 kN, at 15 rad/s with
    WOB 250 kN (the bit turns backwards: the reported failure), stop on bottom and restart,
    lift the bit off with the whole weight on the hook, set it down, drill: no step of the
    mean model or of the germs at delta = 0.3 fails even on dt/16, all values finite, the
    string inside the borehole.
    """
    config, reduced = system
    config = load_config(None, ['reduced_basis.lateral_modes=20',
                                f'integration.time_step_s={dt}'])
    simulator = Simulator(config, members=4, germs=_germs(0.3, 4, 11), system=reduced)
    run = EnvelopeRun(simulator)
    drilling = run.rig.hook_load_command_n
    run.hold(1.0)
    run.hold(2.0, speed=30.0, hook=_wob_hook(simulator, 3e5))
    run.hold(2.0, speed=15.0, hook=_wob_hook(simulator, 2.5e5))
    run.hold(2.0, speed=0.0)                                       # stopped on bottom
    run.hold(1.5, speed=15.0)                                      # restarted
    run.hold(2.0, hook=_weight(simulator) + 4e4)                   # picked up
    run.hold(3.0, hook=_weight(simulator) - 1e5)                   # set down
    run.hold(1.0, speed=5.2, hook=drilling)
    assert run.lifted.all() and run.landed.all()
    print(f'dt = {dt}: {simulator.retries} retried member-steps, {simulator.substeps} '
          f'sub-steps')


@settings.get_profile('envelope')
@given(dt=st.sampled_from([0.01, 0.005]),
       delta=st.sampled_from([0.0, 0.1, 0.3]),
       seed=st.integers(0, 2 ** 16),
       commands=st.lists(st.tuples(st.floats(0.0, 30.0), st.floats(-0.05, 3.0),
                                   st.floats(0.05, 0.6)), min_size=2, max_size=4))
def test_random_command_sequences_inside_the_envelope(system, dt, delta, seed, commands):
    """
    Top speed 0-30 rad/s and static WOB from -50 kN to 300 kN, from a drilling start.

    At -50 kN the bit is lifted (hook above the weight); each is held 0.05-0.6 s.
    """
    config, reduced = system
    config = load_config(None, ['reduced_basis.lateral_modes=20',
                                f'integration.time_step_s={dt}'])
    germs = _germs(delta, 3, seed) if delta else None
    simulator = Simulator(config, members=3, germs=germs, system=reduced)
    run = EnvelopeRun(simulator)
    for speed, wob_100kn, seconds in commands:
        run.hold(seconds, speed=speed, hook=_wob_hook(simulator, 1e5 * wob_100kn))
