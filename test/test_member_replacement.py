"""
A filter's member that cannot be integrated any more is replaced by a copy of another.

An analysis can move a member's law to where the model breaks a physical bound from any
state (a 64-member run of the law's coefficients did at 195 s: bit speed -227 rad/s); that
used to stall the whole ensemble. Checked here: a copied member is the other member from then
on (same state, same law; the same trajectory to the Newton iteration's tolerance: the copy
verifies its first iterates afresh); the guarded batch hands members stalled on a bound to
its ``on_stalled`` and reports the replacement, and without one (or with no healthy member
left) still stalls; the filter draws donors from the member's own pool only and carries the
donor's stored predictions over.
"""
from __future__ import annotations

import numpy as np
import pytest

from drill_twin.assimilation.sequential import SequentialFilter
from drill_twin.assimilation.settings import load_assimilation
from drill_twin.assimilation.state import law_scales_for_members
from drill_twin.config import load_config
from drill_twin.dynamics.simulator import Simulator
from drill_twin.twin.stepping import MAX_CONSECUTIVE_FAILURES, GuardedSimulator, TwinStalled
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
    for _ in range(40):
        simulator.step()
    simulator.copy_members([3], [1])
    np.testing.assert_array_equal(simulator.integrator.germ[3], simulator.integrator.germ[1])
    np.testing.assert_array_equal(simulator.integrator.law_scales[3],
                                  simulator.integrator.law_scales[1])
    for _ in range(200):
        simulator.step()
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

    guarded = GuardedSimulator(simulator, first_member=1, name='ensemble members', guard=guard,
                               on_stalled=replace)
    _run(guarded, MAX_CONSECUTIVE_FAILURES + 10)
    assert handed == [[2]]                          # once, after the limit, that member only
    events = [e for e in guarded.events if e.kind == 'member_replaced']
    assert len(events) == 1 and events[0].level == 'warn'
    assert events[0].values['members'] == '3' and events[0].values['donor'] == '1'
    assert guard.germs_set == 1                     # the guard follows the copied law
    np.testing.assert_array_equal(simulator.integrator.germ[2], simulator.integrator.germ[0])


def test_without_a_replacement_a_stalled_member_still_stalls_the_batch(config):
    guarded = GuardedSimulator(_batch(config, members=2), first_member=1,
                               name='ensemble members', guard=_Breached([1]))
    with pytest.raises(TwinStalled, match=r'ensemble members \[2\] broke a physical bound'):
        _run(guarded, MAX_CONSECUTIVE_FAILURES + 1)
    refusing = GuardedSimulator(_batch(config, members=2), first_member=1,
                                name='ensemble members', guard=_Breached([0, 1]),
                                on_stalled=lambda stalled: {})
    with pytest.raises(TwinStalled):
        _run(refusing, MAX_CONSECUTIVE_FAILURES + 1)


def test_the_filter_draws_donors_from_the_pool_and_carries_their_predictions(config):
    settings = load_assimilation(None, ['assimilation.filter.members=3',
                                        'assimilation.filter.parameters=law'])
    simulator = _batch(config, members=6)              # 3 analysed, 3 open loop
    sequential = SequentialFilter(simulator, 3, settings, np.random.default_rng(0))
    for _ in range(10):
        simulator.step()
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
