"""
Recycled step arrays (drill_twin.numerics.recycled): reused only when no one holds them.

A step's results are handed to its caller as new arrays; the integrator writes a set again
only when nothing but its pool references any array of it. Whatever a caller keeps (an
array, a view of it, a buffer export, a container) must therefore never change.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np
import pytest
from conftest import coarse_string

from drill_twin.numerics.recycled import RecycledArrays
from drill_twin.integrator.simulator import Simulator


def _pool(kept=6):
    return RecycledArrays(lambda: (np.zeros(4), np.zeros((2, 3), dtype=bool)), kept=kept)


def test_a_set_nobody_holds_is_handed_out_again():
    pool = _pool()
    first = pool.take()
    addresses = [a.ctypes.data for a in first]
    del first
    again = pool.take()
    assert [a.ctypes.data for a in again] == addresses
    assert pool.made == 1


@pytest.mark.parametrize('hold', [
    lambda s: s[0],                        # one array of the set
    lambda s: s[1][1:],                    # a view (its base is the set's array)
    lambda s: memoryview(s[0]),            # a buffer export
    lambda s: [s[1]],                      # a container
    lambda s: s[0].T,                      # a transposed view, as the evaluation's full
])
def test_a_set_anything_still_reaches_is_never_written(hold):
    pool = _pool()
    held = hold(pool.take())
    fresh = pool.take()
    assert pool.made == 2
    for array in fresh:
        array[...] = 1
    assert not np.any(np.asarray(held[0] if isinstance(held, list) else held))


def test_a_set_made_as_a_namedtuple_is_handed_out_as_one():
    pair = namedtuple('Pair', 'rates flags')
    pool = RecycledArrays(lambda: pair(rates=np.zeros(4), flags=np.zeros(3, dtype=bool)))
    first = pool.take()
    assert type(first) is pair and first.rates.shape == (4,)
    addresses = [a.ctypes.data for a in first]
    del first
    again = pool.take()
    assert type(again) is pair and [a.ctypes.data for a in again] == addresses
    held = again.flags
    del again
    assert pool.take().flags is not held and pool.made == 2


def test_the_pool_grows_to_what_is_held_and_forgets_past_kept():
    pool = _pool(kept=3)
    kept = [pool.take() for _ in range(5)]        # a caller keeping every set
    assert pool.made == 5
    assert len({a[0].ctypes.data for a in kept}) == 5
    del kept
    pool.take()
    assert pool.made == 5                         # the three it kept are free again
    with pytest.raises(ValueError, match='kept'):
        RecycledArrays(lambda: (), kept=0)


@pytest.fixture(scope='module')
def coarse_system():
    return coarse_string()


def _values(state, result):
    forces = result.forces
    return [a.copy() for a in (state.q, state.q_rate, state.q_acceleration, state.hole_u,
                               result.converged, result.error, forces.full, forces.modal,
                               forces.weight_on_bit_n, forces.bit_jacobian,
                               forces.contact.in_contact, forces.lifted)]


def test_a_simulators_kept_states_and_results_never_change_and_the_rest_is_reused(
        coarse_system):
    config, system = coarse_system
    simulator = Simulator(config, members=3, system=system)
    for _ in range(5):
        simulator.step()
    kept = []
    for _ in range(6):                    # a caller holding every state and result
        result = simulator.step()
        kept.append((simulator.state, result, _values(simulator.state, result)))
    for _ in range(10):
        simulator.step()
    for state, result, values in kept:
        for held, value in zip(_values(state, result), values):
            np.testing.assert_array_equal(held, value)
    pools = simulator.integrator._work.outputs, simulator.integrator._work.kept
    made = [pool.made for pool in pools]
    del kept, state, result
    for _ in range(20):                   # a caller keeping nothing: two sets, then three
        simulator.step()
    assert [pool.made for pool in pools] == made
