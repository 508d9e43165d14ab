"""
The ensemble hangs every member's drill line from the rig's block.

With the drawworks, the mean model's block moves; each member's line pulls its own hook load
from that block, H_m = H_S + k_l (u_top,m - x_b - s_m) + c_l (u_top,m' - v_b)
(docs/DRIVES.md, "Mean model and ensemble"). Members that took the mean model's hook load as
a force instead would fall further, where their hole is deeper than the mean model's, when
the mean model sets down.
"""
from __future__ import annotations

import numpy as np
import pytest

from drill_twin.config import load_config
from drill_twin.twin.engine import TwinEngine
from drill_twin.twin.ensemble import EnsembleSettings

pytestmark = pytest.mark.slow       # the module's engine runs for about 30 s

LIGHT = ['reduced_basis.lateral_modes=2', 'physics.contact=false',
         'physics.finite_strain=false', 'physics.kinetic_coupling=false',
         'initial_conditions.lateral_deflection_m=0', 'integration.time_step_s=0.01',
         'initial_conditions.steady_twist=true', 'operation.top_drive_speed_hz=0.3183']


@pytest.fixture(scope='module')
def picked_up():
    config = load_config(overrides=LIGHT)
    engine = TwinEngine(config, EnsembleSettings(members=6, dispersion=0.1, seed=2))
    ensemble = engine.ensemble_runner.simulator
    rows = []

    def run(seconds):
        for _ in range(int(round(seconds / 0.01))):
            engine.advance(1)
            drawworks = engine.rig.drawworks
            o = ensemble.observe()
            rows.append((engine.time_s,
                         None if drawworks is None else drawworks.state.block_position_m,
                         o.hook_position_m.copy(), np.broadcast_to(o.hook_load_n, (6,)).copy(),
                         o.hole_depth_m - o.bit_depth_m, o.on_bottom.copy()))

    def gap():
        o = engine.simulator.observe(detailed=1)
        return float(o.hole_depth_m[0] - o.bit_depth_m[0])

    run(8.0)                                           # drilling, hook load
    engine.set_axial_mode('block_velocity')
    engine.set_block_velocity(-0.1)
    run(15.0)                                          # up about 1.4 m
    engine.set_block_velocity(0.0)
    run(3.0)
    engine.set_block_velocity(0.1)
    while gap() > 0.3:
        run(0.1)
    engine.set_block_velocity(0.01)                    # tag bottom gently, as a driller does
    while gap() > 0.0:
        run(0.1)
    run(3.0)
    engine.set_weight_on_bit_setpoint(80e3)
    engine.set_axial_mode('autodriller')
    run(10.0)
    yield engine, ensemble, rows
    engine.close()


def test_every_member_hangs_from_the_block(picked_up):
    engine, ensemble, rows = picked_up
    block = [r for r in rows if r[1] is not None]
    # Each member's top followed the block: its rise equals the block's less the change of its
    # line's stretch (hook load / k_l), and the members' hook loads are their own.
    k = engine.config.drawworks.line_stiffness_n_per_m
    first, up = block[0], max(block, key=lambda r: -r[1])
    rise_block = first[1] - up[1]
    rise_tops = first[2] - up[2]
    stretch = (first[3] - up[3]) / k
    assert rise_block > 1.3
    np.testing.assert_allclose(rise_tops, rise_block - stretch, atol=0.02 * rise_block)
    assert np.ptp(up[3]) > 0.0                         # one hook load per member
    assert np.all(up[4] > 1.0)                         # every bit off bottom
    assert engine.rig.drawworks is not None and engine.axial_mode == 'autodriller'


def test_members_set_down_and_drill_without_a_reset(picked_up):
    engine, ensemble, rows = picked_up
    assert engine.ensemble_runner.guarded.resets == 0 and engine.resets == 0
    assert np.all(rows[-1][5])                         # every member back on bottom
