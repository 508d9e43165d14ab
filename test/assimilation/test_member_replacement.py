"""
A filter's member that cannot be integrated any more is replaced by a copy of another.

An analysis can move a member's law to where the model breaks a physical bound from any
state (a 64-member run of the law's coefficients reaches one at 195 s: bit speed
-227 rad/s); kept, such a member would stall the whole ensemble. Checked here: a copied
member is the other member from then on (same state, same law; the same trajectory to the
Newton iteration's tolerance: the copy verifies its first iterates afresh); the guarded
batch hands members stalled on a bound to its ``on_stalled`` and reports the replacement,
and without one (or with no healthy member left) still stalls; the filter draws donors from
the member's own pool only and carries the donor's stored predictions over. The twin's
open-loop ensemble (no filter) gives such a member a healthy member's state under a fresh
draw of the germ (the next realization of its study).
"""
from __future__ import annotations

import numpy as np
import pytest

from drill_twin.assimilation.sequential import SequentialFilter
from drill_twin.assimilation.settings import load_assimilation
from drill_twin.assimilation.state import law_scales_for_members
from drill_twin.config import load_config
from drill_twin.model.reduced_system import build_reduced_system
from drill_twin.integrator.simulator import Simulator
from drill_twin.modal.reduced_basis import modal_analysis
from drill_twin.twin.ensemble import EnsembleSettings, LocalEnsemble
from drill_twin.integrator.stepping import MAX_CONSECUTIVE_FAILURES, GuardedSimulator, TwinStalled
from drill_twin.rig.rig import Rig
from drill_twin.uncertainty.germ import germs_for_realizations

SMALL = ['sections.drill_pipe.elements=8', 'sections.drill_collar.elements=4',
         'reduced_basis.lateral_modes=6']


@pytest.fixture(scope='module')
def config():
    return load_config(None, SMALL)


def _batch(config, members=4):
    scales = law_scales_for_members(0.15, 5, members)
    return Simulator(config, members, germs=germs_for_realizations(0.2, 0, range(members)),
                     law_scales=scales)


def test_a_copied_member_is_the_other_member_from_then_on(config):
    simulator = _batch(config)
    rig = Rig(simulator)
    for _ in range(40):
        rig.step()
    simulator.copy_members([3], [1])
    np.testing.assert_array_equal(simulator.integrator.germ[3], simulator.integrator.germ[1])
    np.testing.assert_array_equal(simulator.integrator.law_scales[3],
                                  simulator.integrator.law_scales[1])
    for _ in range(200):
        rig.step()
    seen = simulator.observe()
    for name in ('speed_rad_per_s', 'weight_on_bit_n', 'torque_on_bit_nm'):
        values = getattr(seen, name)
        assert values[3] == pytest.approx(values[1], rel=1e-9)
        assert values[2] != pytest.approx(values[1], rel=1e-3)      # the others are not
    np.testing.assert_allclose(simulator.state.q[3], simulator.state.q[1], rtol=1e-8,
                               atol=1e-9 * np.abs(simulator.state.q[1]).max())
    assert simulator.hole_depth_m[3] == pytest.approx(simulator.hole_depth_m[1], abs=1e-9)


class _Breached:
    """A guard under which some members break a bound at every step, whatever their state."""

    def __init__(self, members):
        self.members = set(members)
        self.germs_set = 0

    def check(self, simulator):
        return {m: 'bit speed -227 rad/s is beyond +-150 rad/s' for m in self.members}

    def set_germs(self, germs, law_scales=None):
        self.germs_set += 1


def _run(guarded, steps):
    for _ in range(steps):
        guarded.step()


def test_a_member_stalled_on_a_bound_is_handed_over_and_reported(config):
    simulator = _batch(config, members=3)
    guard = _Breached([2])
    handed = []

    def replace(stalled):
        handed.append(list(stalled))
        simulator.copy_members([2], [0])
        guard.members.clear()                      # the copy is plausible
        return {2: 0}

    guarded = GuardedSimulator(Rig(simulator), first_member=1, name='ensemble members',
                               guard=guard, on_stalled=replace)
    _run(guarded, MAX_CONSECUTIVE_FAILURES + 10)
    assert handed == [[2]]                          # once, after the limit, that member only
    events = [e for e in guarded.events if e.kind == 'member_replaced']
    assert len(events) == 1 and events[0].level == 'warn'
    assert events[0].values['members'] == '3' and events[0].values['donor'] == '1'
    assert guard.germs_set == 1                     # the guard follows the copied law
    np.testing.assert_array_equal(simulator.integrator.germ[2], simulator.integrator.germ[0])


def test_without_a_replacement_a_stalled_member_still_stalls_the_batch(config):
    guarded = GuardedSimulator(Rig(_batch(config, members=2)), first_member=1,
                               name='ensemble members', guard=_Breached([1]))
    with pytest.raises(TwinStalled, match=r'ensemble members \[2\] broke a physical bound'):
        _run(guarded, MAX_CONSECUTIVE_FAILURES + 1)
    refusing = GuardedSimulator(Rig(_batch(config, members=2)), first_member=1,
                                name='ensemble members', guard=_Breached([0, 1]),
                                on_stalled=lambda stalled: {})
    with pytest.raises(TwinStalled):
        _run(refusing, MAX_CONSECUTIVE_FAILURES + 1)


def test_one_plausible_step_ends_a_run_of_breaches(config):
    """A member stalls after MAX_CONSECUTIVE_FAILURES breaches in a row, not in all."""
    guard = _Breached([])
    guarded = GuardedSimulator(Rig(_batch(config, members=2)), first_member=1,
                               name='ensemble members', guard=guard)
    for _ in range(3):                                # runs one short of the limit
        guard.members = {1}
        _run(guarded, MAX_CONSECUTIVE_FAILURES - 1)
        guard.members = set()
        _run(guarded, 1)
    guard.members = {1}
    _run(guarded, MAX_CONSECUTIVE_FAILURES - 1)
    with pytest.raises(TwinStalled, match=rf'\[2\] broke a physical bound in '
                                          rf'{MAX_CONSECUTIVE_FAILURES} steps'):
        _run(guarded, 1)


def test_the_filter_draws_donors_from_the_pool_and_carries_their_predictions(config):
    settings = load_assimilation(None, ['assimilation.filter.members=3',
                                        'assimilation.filter.parameters=law'])
    simulator = _batch(config, members=6)              # 3 analysed, 3 open loop
    rig = Rig(simulator)
    sequential = SequentialFilter(simulator, 3, settings, np.random.default_rng(0))
    for _ in range(10):
        rig.step()
        sequential.after_step()
    replaced = sequential.replace_stalled([1, 4, 5], [range(3), range(3, 6)])
    assert replaced[1] in (0, 2) and replaced[4] == 3 and replaced[5] == 3
    for target, donor in replaced.items():
        np.testing.assert_array_equal(simulator.state.q[target], simulator.state.q[donor])
        np.testing.assert_array_equal(simulator.integrator.law_scales[target],
                                      simulator.integrator.law_scales[donor])
    np.testing.assert_array_equal(sequential._predicted[:, 1],
                                  sequential._predicted[:, replaced[1]])
    assert sequential.replaced == 3
    assert sequential.replace_stalled([0, 1, 2]) == {}  # no healthy member left in the pool


def test_a_copy_under_a_new_germ_follows_its_own_law(config):
    """
    copy_members(germs=...): the donor's state under the new germ, which it then follows.

    Given the donor's own germ the copy is the donor (as a plain copy); given another germ it
    drills by that law from the next step on, not the donor's.
    """
    simulator = _batch(config)
    rig = Rig(simulator)
    for _ in range(40):
        rig.step()
    simulator.copy_members([3], [1], germs=simulator.integrator.germ[1][None].copy())
    new_germ = germs_for_realizations(0.2, 0, [17])
    simulator.copy_members([2], [1], germs=new_germ)
    np.testing.assert_array_equal(simulator.integrator.germ[2], new_germ[0])
    np.testing.assert_array_equal(simulator.integrator.law_scales[2],
                                  simulator.integrator.law_scales[1])
    for name in ('q', 'q_rate', 'q_acceleration'):
        np.testing.assert_array_equal(getattr(simulator.state, name)[2],
                                      getattr(simulator.state, name)[1])
    for _ in range(100):
        rig.step()
    seen = simulator.observe()
    assert seen.weight_on_bit_n[3] == pytest.approx(seen.weight_on_bit_n[1], rel=1e-6)
    assert seen.torque_on_bit_nm[2] != pytest.approx(seen.torque_on_bit_nm[1], rel=1e-3)
    with pytest.raises(ValueError, match='germs'):
        Simulator(config, 2).copy_members([1], [0], germs=new_germ)


def test_the_open_loop_ensemble_redraws_a_stalled_member_and_goes_on(config):
    """
    An open-loop member stalled on a bound takes a healthy state and realization N's germ.

    The member is redrawn (reported as member_replaced) rather than the ensemble dropped
    whole, and the ensemble goes on; the next one stalled takes realization N + 1
    (docs/ENVELOPE.md, "A step that cannot fail, and what happens if one does").
    """
    model, _, basis = modal_analysis(config)
    settings = EnsembleSettings(members=3, dispersion=0.2, seed=7)
    ensemble = LocalEnsemble(config, settings, build_reduced_system(model, basis))
    guard = _Breached([1])
    ensemble.guarded.guard = guard
    speed = ensemble.rig.top_drive.speed_rad_per_s
    events = []
    for _ in range(MAX_CONSECUTIVE_FAILURES // 2 + 5):
        ensemble.start(2, np.full(2, speed), ensemble.simulator.state.hook_load_n)
        result = ensemble.collect()
        events += [e for e in result.events if e.kind == 'member_replaced']
        if events:
            guard.members.clear()                  # the redrawn member is plausible
    assert len(events) == 1 and 'fresh draw of the germ' in events[0].message
    assert events[0].values['members'] == '2'      # member 1 of the batch is ensemble member 2
    germ = ensemble.simulator.integrator.germ
    np.testing.assert_array_equal(germ[1], germs_for_realizations(0.2, 7, [3])[0])
    np.testing.assert_array_equal(germ[[0, 2]], germs_for_realizations(0.2, 7, [0, 2]))
    assert guard.germs_set == 1
    replaced, germs = ensemble._redraws.choose([2], 3)
    assert replaced[2] in (0, 1)
    np.testing.assert_array_equal(germs, germs_for_realizations(0.2, 7, [4]))
    assert ensemble._redraws.choose([0, 1, 2], 3) == ({}, None)    # no healthy member left
