"""
Off bottom and back: drill, pick up 2 m, rotate off bottom, set back down, drill again.

The hook load is the only axial command of the model. A driller moves the block at a speed;
here a PI loop on the top's axial velocity sets the hook load (without knowing what the
string weighs), as a drawworks' speed control does, while the bit is lifted and set down;
drilling is at a constant hook load.

The string is the paper's in axial and torsional motion at 2 rad/s (steady drilling: below
the velocity-weakening branch), with two lateral modes and no wall contact, finite strain or
kinetic coupling: none of them acts on a straight string, and the run stays short.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from drill_twin.config import load_config
from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.integrator.simulator import Simulator
from drill_twin.rig.rig import Rig

SPEED = 2.0                        # rad/s
PICK_UP_M = 2.0
GAIN_N_S_PER_M = 2.0e5             # PI velocity loop of the "drawworks"
INTEGRAL_N_PER_M = 8.0e4


class Driller:
    """Steps the simulator and keeps what the test checks."""

    def __init__(self, simulator: Simulator):
        self.sim = simulator
        self.rig = Rig(simulator)
        self.integral = 0.0
        self.rows = []

    def step(self):
        self.rig.step()
        o = self.sim.observe(detailed=1)
        self.rows.append((self.sim.time_s, o.bit_depth_m[0], o.hole_depth_m[0], o.on_bottom[0],
                          o.rop_m_per_s[0], o.weight_on_bit_n[0], o.torque_on_bit_nm[0],
                          o.speed_rad_per_s[0], o.hook_load_n, o.hook_velocity_m_per_s[0],
                          o.landings_so_far[0], o.bit_axial_velocity_m_per_s[0]))
        return o

    def drill(self, seconds, hook_load_n):
        self.rig.set_hook_load(hook_load_n)
        for _ in range(_steps(self.sim, seconds)):
            self.step()

    def ramp(self, seconds, hook_load_n):
        start = self.rig.hook_load_command_n
        n = _steps(self.sim, seconds)
        for k in range(1, n + 1):
            self.rig.set_hook_load(start + (hook_load_n - start) * k / n)
            self.step()

    def move_block(self, speed_m_per_s, until, limit_s=60.0):
        """PI loop on the top's velocity (m/s, > 0 down) until ``until(observation)``."""
        o = self.sim.observe(detailed=1)
        base = self.rig.hook_load_command_n - self.integral
        for _ in range(_steps(self.sim, limit_s)):
            error = o.hook_velocity_m_per_s[0] - speed_m_per_s
            self.integral += INTEGRAL_N_PER_M * error * self.sim.dt
            self.rig.set_hook_load(base + GAIN_N_S_PER_M * error + self.integral)
            o = self.step()
            if until(o):
                return
        raise AssertionError(f'block move at {speed_m_per_s} m/s did not end in {limit_s} s')

    def table(self):
        names = ('t', 'bit', 'hole', 'on_bottom', 'rop', 'wob', 'tob', 'omega', 'hook',
                 'hook_velocity', 'landings', 'bit_velocity')
        data = np.array(self.rows)
        return {name: data[:, k] for k, name in enumerate(names)}


def _steps(simulator, seconds):
    return int(round(seconds / simulator.dt))


@pytest.fixture(scope='module')
def sequence():
    config = load_config(None, [
        f'operation.top_drive_speed_hz={SPEED / (2 * math.pi)}',
        'initial_conditions.steady_twist=true', 'initial_conditions.lateral_deflection_m=0',
        'reduced_basis.lateral_modes=2', 'physics.contact=false',
        'physics.finite_strain=false', 'physics.kinetic_coupling=false',
        'integration.time_step_s=0.01'])
    simulator = Simulator(config)
    prestress = simulator.system.model.prestress
    weight = prestress.hook_load_n - config.bit_rock.static_weight_on_bit_n
    driller = Driller(simulator)
    marks = {}
    driller.drill(6.0, prestress.hook_load_n)
    marks['drilled'] = simulator.time_s
    start_depth = driller.table()['hole'][-1]
    driller.move_block(-0.25, lambda o: o.bit_depth_m[0] < start_depth - PICK_UP_M + 0.15)
    driller.move_block(0.0, lambda o: abs(o.hook_velocity_m_per_s[0]) < 1e-3
                       and abs(o.bit_axial_velocity_m_per_s[0]) < 1e-3)
    marks['lifted'] = simulator.time_s
    driller.move_block(0.0, lambda o: False if simulator.time_s < marks['lifted'] + 6.0
                       else True)                     # rotate off bottom, hovering
    marks['hovered'] = simulator.time_s
    driller.move_block(0.25, lambda o: o.bit_depth_m[0] > o.hole_depth_m[0] - 0.3)
    driller.move_block(0.05, lambda o: bool(o.on_bottom[0]))
    marks['landed'] = simulator.time_s
    driller.ramp(8.0, prestress.hook_load_n)
    driller.drill(24.0, prestress.hook_load_n)
    return config, simulator, driller.table(), marks, weight, start_depth


def test_the_hole_never_gets_shallower_and_the_bit_went_up_two_metres(sequence):
    """
    The hole only deepens; the bit is never below it by more than it presses the rock.

    The rock under the bit is a spring of ``bit_rock.contact_stiffness_n_per_m``: the bit
    on bottom is WOB / k below the hole's (undeformed) bottom, 1 mm at 100 kN.
    """
    config, simulator, table, marks, _, start_depth = sequence
    assert np.all(np.diff(table['hole']) >= 0)
    pressed = np.maximum(-table['wob'], 0.0) / config.bit_rock.contact_stiffness_n_per_m
    assert np.all(table['bit'] <= table['hole'] + pressed + 1e-6)
    drilling = table['t'] > marks['landed'] + 20.0
    np.testing.assert_allclose((table['bit'] - table['hole'])[drilling], pressed[drilling],
                               atol=1e-6)
    highest = np.min(table['bit'])
    assert start_depth - highest == pytest.approx(PICK_UP_M, abs=0.2)
    off = table['on_bottom'] == 0
    assert np.all(table['rop'][off] == 0)                  # ROP: the hole's deepening rate
    assert np.all(table['wob'][off] == 0) and np.all(table['tob'][off] == 0)
    lifted = (table['t'] > marks['lifted']) & (table['t'] <= marks['hovered'])
    # While the bit is 2 m up the hole does not move.
    assert np.ptp(table['hole'][lifted]) == 0.0
    assert simulator.retries == 0


def test_off_bottom_the_hook_carries_the_strings_weight(sequence):
    """
    Hovering, the hook load found by the velocity loop is the string's weight.

    The velocity loop does not know the weight; the hook load is the string's weight as the
    model counts it, H_S - f_c, within the damping drag.
    """
    config, simulator, table, marks, weight, _ = sequence
    model = simulator.system.model
    mass = np.sum(model.mesh.density_kg_per_m3 * model.mesh.area_m2 * model.mesh.length_m)
    hover = (table['t'] > marks['hovered'] - 1.0) & (table['t'] <= marks['hovered'])
    drag = config.damping.mass_coefficient_per_s * mass * np.abs(table['hook_velocity'][hover])
    assert np.all(np.abs(table['hook'][hover] - weight) <= drag + 1e-3 * weight)
    assert np.mean(table['hook'][hover]) == pytest.approx(weight, rel=2e-4)
    # Rotating off bottom: the bit swings about the top speed (the torsional mode the pick-up
    # released, barely damped with no rock), with no torque at the bit.
    off = table['on_bottom'] == 0
    assert np.mean(table['omega'][off]) == pytest.approx(SPEED, rel=0.1)
    assert np.ptp(table['omega'][off]) > 1.0


def test_the_landing_is_detected(sequence):
    """
    The bit tags bottom when it reaches the hole bottom.

    Landing turning backwards (the torsional swing of a string spun off bottom) it rests on the
    rock, the string's axial wave bounces it a few times, then it stays on bottom.
    """
    _, _, table, marks, _, _ = sequence
    first = np.flatnonzero(table['landings'] > 0)[0]
    assert table['t'][first] == pytest.approx(marks['landed'])
    assert table['hole'][first] - table['bit'][first - 1] > 0      # it came from above
    settled = table['t'] > marks['landed'] + 3.0
    assert np.all(table['on_bottom'][settled] == 1)
    assert table['landings'][-1] <= 10


def test_drilling_resumes_at_the_same_stationary_rop(sequence):
    """
    The bit drills at the law's ROP before the pick-up and, on average, after the set-down.

    Before the pick-up the bit drills steadily at the law's ROP for the top speed and the
    weight on bit; after the set-down it drills at the same ROP on average (the torsional swing
    of the landing still decays: 8 % rms 20 s later, damped by the law).
    """
    config, _, table, marks, _, _ = sequence
    law = BitRockLaw.from_config(config.bit_rock)
    before = (table['t'] > marks['drilled'] - 2.0) & (table['t'] <= marks['drilled'])
    np.testing.assert_allclose(table['omega'][before], SPEED, rtol=1e-3)
    expected = law.steady_rop(SPEED, table['wob'][before])
    np.testing.assert_allclose(table['rop'][before], expected, rtol=1e-3)
    after = table['t'] > table['t'][-1] - 10.0
    wob = np.mean(table['wob'][after])
    assert wob == pytest.approx(config.bit_rock.static_weight_on_bit_n, rel=5e-3)
    assert np.mean(table['omega'][after]) == pytest.approx(SPEED, rel=5e-3)
    assert np.mean(table['rop'][after]) == pytest.approx(law.steady_rop(SPEED, wob), rel=1e-2)
    assert np.mean(table['rop'][after]) == pytest.approx(np.mean(table['rop'][before]), rel=1e-2)
    swing = table['t'] > marks['landed'] + 8.0
    early = swing & (table['t'] <= marks['landed'] + 18.0)
    assert np.std(table['rop'][after]) < np.std(table['rop'][early])    # and it decays
