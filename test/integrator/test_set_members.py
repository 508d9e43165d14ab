"""Simulator.set_members: an analysis step moves members; they then step as that state does."""
from __future__ import annotations

import numpy as np
import pytest

from drill_twin.config import load_config
from drill_twin.integrator.simulator import Simulator
from drill_twin.uncertainty.germ import germs_for_realizations

LIGHT = ['reduced_basis.lateral_modes=2', 'physics.contact=false',
         'physics.finite_strain=false', 'physics.kinetic_coupling=false',
         'initial_conditions.lateral_deflection_m=0', 'integration.time_step_s=0.01']


def test_a_member_given_anothers_state_and_germ_steps_as_it_does():
    config = load_config(overrides=LIGHT)
    germs = germs_for_realizations(0.1, 0, [0, 1])
    simulator = Simulator(config, members=2, germs=germs)
    for _ in range(100):
        simulator.step()
    state = simulator.state
    gap = np.max(np.abs(state.q[0] - state.q[1]))          # the two germs' runs differ
    assert gap > 1e-4
    simulator.set_members(state.q[1:2].copy(), state.q_rate[1:2].copy(),
                          simulator.hole_u()[1:2].copy(), germs=germs[1:2])
    landings = simulator.landing_count.copy()
    # The accelerations are solved from the equations of motion at the new state; member 1's
    # are the last step's, converged to the Newmark tolerance (1e-6).
    np.testing.assert_allclose(simulator.state.q_acceleration[0],
                               simulator.state.q_acceleration[1], rtol=1e-4, atol=1e-6)
    for _ in range(100):
        simulator.step()
    # 100 steps later the two agree to the Newmark tolerance, not to the germs' gap.
    assert np.max(np.abs(simulator.state.q[0] - simulator.state.q[1])) < 1e-6 * gap
    assert abs(simulator.hole_u()[0] - simulator.hole_u()[1]) < 1e-6 * gap
    np.testing.assert_array_equal(simulator.landing_count, landings)


def test_set_members_refuses_what_it_cannot_do():
    simulator = Simulator(load_config(overrides=LIGHT))
    q, rate = simulator.state.q.copy(), simulator.state.q_rate.copy()
    with pytest.raises(ValueError, match='mean model'):
        simulator.set_members(q, rate, simulator.hole_u(), germs=np.eye(2)[None])
    with pytest.raises(ValueError, match='2 members given'):
        simulator.set_members(np.vstack([q, q]), np.vstack([rate, rate]),
                              np.zeros(2))
