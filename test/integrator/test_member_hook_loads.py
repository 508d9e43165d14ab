"""One hook load per member: each member steps as a batch of one under its own hook load."""
from __future__ import annotations

import numpy as np
import pytest

from drill_twin.config import load_config
from drill_twin.integrator.simulator import Simulator
from drill_twin.rig.rig import Rig

LIGHT = ['reduced_basis.lateral_modes=2', 'physics.contact=false',
         'physics.finite_strain=false', 'physics.kinetic_coupling=false',
         'initial_conditions.lateral_deflection_m=0', 'integration.time_step_s=0.01',
         'initial_conditions.steady_twist=true']


def test_members_under_their_own_hook_loads_step_as_single_runs():
    config = load_config(overrides=LIGHT)
    batch = Simulator(config, members=3)
    weight = batch.system.model.prestress.hook_load_n - config.bit_rock.static_weight_on_bit_n
    loads = np.array([weight - 150e3, weight + 1.0e3, weight - 60e3])   # drill, lift, drill
    singles = [Simulator(config) for _ in loads]
    batch_rig, rigs = Rig(batch), [Rig(single) for single in singles]
    batch_rig.set_hook_load(loads)
    for rig, load in zip(rigs, loads):
        rig.set_hook_load(float(load))
    for _ in range(300):
        batch_rig.step()
        for rig in rigs:
            rig.step()
    for k, single in enumerate(singles):                # to the products' round-off
        np.testing.assert_allclose(batch.state.q[k], single.state.q[0], rtol=1e-11, atol=1e-12)
        np.testing.assert_allclose(batch.hole_u()[k], single.hole_u()[0], rtol=1e-13)
    observed = batch.observe(detailed=1)
    np.testing.assert_array_equal(observed.hook_load_n, loads)
    assert not observed.on_bottom[1] and observed.on_bottom[0] and observed.on_bottom[2]


def test_the_steps_counts_are_its_flags_and_a_landing_is_counted():
    """
    The kernel counts the bits on bottom and lifted off (StepResult.members_on_bottom, _lifted).

    The Simulator's landing and lift-off bookkeeping reads those counts: member 1, lifted by its
    hook load, lands when the load drops again, and only it is counted.
    """
    from drill_twin.integrator.newmark import merged_result

    config = load_config(overrides=LIGHT)
    batch = Simulator(config, members=3)
    rig = Rig(batch)
    weight = batch.system.model.prestress.hook_load_n - config.bit_rock.static_weight_on_bit_n
    rig.set_hook_load(np.array([weight - 150e3, weight + 1.0e3, weight - 60e3]))
    seen_off, seen_lifted = False, False
    for step in range(400):
        if step == 200:
            rig.set_hook_load(np.array([weight - 150e3, weight - 150e3, weight - 60e3]))
        result = rig.step()
        assert result.members_on_bottom == np.count_nonzero(result.on_bottom)
        assert result.members_lifted == np.count_nonzero(result.forces.lifted)
        seen_off |= result.members_on_bottom < 3
        seen_lifted |= result.members_lifted > 0
    assert seen_off and seen_lifted
    assert batch.landing_count[1] >= 1 and batch.landing_count[0] == batch.landing_count[2] == 0
    assert batch.lift_off_count[1] >= 1 and batch.lift_off_count[0] == batch.lift_off_count[2] == 0
    assert batch.on_bottom().all()
    merged = merged_result(result, message='m')
    assert (merged.on_bottom, merged.members_on_bottom, merged.members_lifted) == (None,) * 3


def test_hook_loads_of_the_wrong_shape_are_refused():
    config = load_config(overrides=LIGHT)
    batch = Simulator(config, members=3)
    with pytest.raises(ValueError, match=r'shape \(3,\)'):
        batch.step(config.operation.top_drive_speed_rad_per_s, np.ones(2))
    with pytest.raises(ValueError, match=r'shape \(3,\)'):
        Rig(batch).set_hook_load(np.ones(2))
