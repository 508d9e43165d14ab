"""
The ensemble turns with the rig's top drive (docs/DRIVES.md, "Mean model and ensemble").

The members take the top speed the mean model's drive gave in each step, whatever the drive:
the kinematic ramp, or the dynamic drive under a stick-slip controller switched on at run
time. Members that kept the configured kinematic drive under the speed set-point would give
confidence bounds for a string the rig is not turning.

With dispersion 0 every member is the mean model, so each member must reproduce the mean
model's bit speed, step for step, one tick later.
"""
from __future__ import annotations

import numpy as np
import pytest

from drill_twin.config import load_config
from drill_twin.twin.engine import TwinEngine
from drill_twin.twin.ensemble import EnsembleSettings

TORSIONAL_AXIAL = ['physics.contact=false', 'physics.kinetic_coupling=false',
                   'physics.finite_strain=false', 'reduced_basis.lateral_modes=0',
                   'initial_conditions.lateral_deflection_m=0', 'integration.time_step_s=0.01',
                   'bit_rock.static_weight_on_bit_n=-100000']
STEPS_PER_TICK = 2


@pytest.fixture(scope='module', params=[False, True], ids=['in-process', 'worker-process'])
def run(request):
    config = load_config(overrides=TORSIONAL_AXIAL)
    engine = TwinEngine(config, EnsembleSettings(members=3, dispersion=0.0,
                                                 separate_process=request.param))
    mean, members = {}, {}
    try:
        for tick in range(1000):                        # 20 s
            if tick == 250:                             # 5 s: the rig switches its drive
                engine.set_top_drive_controller('impedance')
                engine.set_top_drive_mode('dynamic')
            snapshot = engine.advance(STEPS_PER_TICK)
            top = engine.simulator.state.top_speed_rad_per_s
            mean[round(engine.time_s, 6)] = (snapshot.bit.speed_rad_per_s, top)
            latest = engine.ensemble_runner.collect()     # this tick's, at once
            members[round(latest.time_s, 6)] = latest.bit[:, 4].copy()
        yield engine, mean, members
    finally:
        engine.close()


def test_the_members_turn_with_the_dynamic_drive_switched_at_run_time(run):
    engine, mean, members = run
    assert engine.top_drive_mode == 'dynamic'
    times = sorted(t for t in members if t in mean and t > 0.0)
    assert len(times) == 1000 and times[-1] == pytest.approx(20.0)
    after = [t for t in times if t > 6.0]
    top = np.array([mean[t][1] for t in after])
    # The dynamic drive under the impedance law moves the top speed although the set-point
    # stays: a member under the kinematic drive would turn at the set-point.
    assert np.ptp(top) > 0.5
    assert engine.top_drive_speed_command == pytest.approx(config_speed(engine))
    bit_mean = np.array([mean[t][0] for t in times])
    bit_members = np.array([members[t] for t in times])
    assert np.ptp(bit_mean[np.array(times) > 6.0]) > 0.5
    np.testing.assert_allclose(bit_members, bit_mean[:, None].repeat(3, axis=1),
                               rtol=0.0, atol=1e-6)


def config_speed(engine) -> float:
    return engine.config.operation.top_drive_speed_rad_per_s
