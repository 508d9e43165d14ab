"""
Loading the compiled step at set-up leaves no trace on the run.

The simulator steps once and drops the step when it is built, so that numba loads its kernels
then and not in the time loop's first step (``NewmarkIntegrator.load_kernels``). These tests
compare runs bit for bit with and without that step.
"""
from __future__ import annotations

import numpy as np
import pytest

from drill_twin.integrator.newmark import NewmarkIntegrator
from drill_twin.model.reduced_system import build_reduced_system
from drill_twin.integrator.simulator import Simulator
from drill_twin.uncertainty.germ import germs_for_realizations

MEMBERS = 3
STEPS = 40


@pytest.fixture(scope='module')
def system(default_analysis):
    model, _, basis = default_analysis
    return build_reduced_system(model, basis)


def _simulator(config, system):
    return Simulator(config, members=MEMBERS, system=system,
                     germs=germs_for_realizations(0.1, 7, range(MEMBERS)))


def _run(simulator, steps, load_after=None):
    """Step ``steps`` times (loading the kernels again after step ``load_after``); the states."""
    states = []
    for k in range(steps):
        simulator.step()
        states.append((simulator.state.q.copy(), simulator.state.q_rate.copy(),
                       simulator.last.weight_on_bit_n.copy()))
        if k == load_after:
            integrator, state = simulator.integrator, simulator.state
            counters = vars(integrator.counters).copy()
            integrator.load_kernels(state, state.top_speed_rad_per_s, 9e5)
            assert vars(integrator.counters) == counters
    return states


def _same(first, second):
    for a, b in zip(first, second, strict=True):
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x, y)


def test_the_set_up_step_changes_nothing(default_config, system, monkeypatch):
    loaded = _simulator(default_config, system)
    counters = vars(loaded.integrator.counters).copy()
    assert counters['steps'] == 0                  # the set-up step is not counted
    with monkeypatch.context() as patch:
        patch.setattr(NewmarkIntegrator, 'load_kernels', lambda self, *args: None)
        plain = _simulator(default_config, system)
    _same(_run(loaded, STEPS), _run(plain, STEPS))
    assert vars(loaded.integrator.counters) == vars(plain.integrator.counters)


def test_a_load_mid_run_changes_nothing(default_config, system):
    """Later, with contraction rates and flags in use, and another hook load."""
    _same(_run(_simulator(default_config, system), STEPS, load_after=STEPS // 2),
          _run(_simulator(default_config, system), STEPS))
