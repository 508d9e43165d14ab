"""
The drawworks (docs/DRIVES.md, "The drawworks").

Block-velocity input with the hook load measured, static equilibrium of the string against its
weight, the autodriller's step response against the linearised closed form, and run-time
switching.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from drill_twin.config import load_config
from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.integrator.envelope import StringEnvelope
from drill_twin.integrator.simulator import SimulationDiverged, Simulator
from drill_twin.rig.drawworks import line_hook_load_n
from drill_twin.rig.rig import Rig

QUIET = ['physics.contact=false', 'physics.kinetic_coupling=false',
         'physics.finite_strain=false', 'reduced_basis.lateral_modes=0',
         'initial_conditions.lateral_deflection_m=0', 'initial_conditions.steady_twist=true',
         'operation.top_drive_speed_hz=2.0', 'bit_rock.static_weight_on_bit_n=-80e3',
         'integration.time_step_s=0.01']
"""The paper's string without lateral motion, drilling at 2 Hz and 80 kN: no stick-slip."""


def _steady_rop(config):
    law = BitRockLaw.from_config(config.bit_rock)
    return float(law.steady_rop(config.operation.top_drive_speed_rad_per_s,
                                config.bit_rock.static_weight_on_bit_n))


def test_block_velocity_holds_the_string_in_static_equilibrium():
    """
    The block lowered at the steady ROP.

    The measured hook load is the string's weight as the model counts it (envelope: W = H_S -
    f_c) minus the WOB, within the damping drag.
    """
    config = load_config(overrides=QUIET)
    rop = _steady_rop(config)
    config = load_config(overrides=QUIET + ['drawworks.mode=block_velocity',
                                            f'drawworks.block_velocity_m_per_s={rop}'])
    simulator = Simulator(config)
    rig = Rig(simulator)
    drawworks = rig.drawworks
    envelope = StringEnvelope.of(simulator.system)
    balance, drag = [], []
    for k in range(int(round(6.0 / simulator.dt))):
        rig.step()
        if simulator.time_s > 3.0:
            observed = simulator.observe(detailed=1)
            hook = line_hook_load_n(drawworks)
            # The force applied (solved with the bit force of the last step) is what the line
            # pulls at the end of the step, to the lag of the bit force (about 1e-4 N here).
            assert hook == pytest.approx(observed.hook_load_n, abs=1.0)
            balance.append(hook - observed.weight_on_bit_n[0] - envelope.string_weight_n)
            drag.append(envelope.axial_drag_n_s_per_m * observed.hook_velocity_m_per_s[0])
    drag = float(np.mean(drag))
    assert drag > 0
    # H + WOB + C v = W: the residual is the drag, up to 2 C v.
    assert np.max(np.abs(balance)) <= 2.0 * drag
    assert -np.mean(balance) == pytest.approx(drag, rel=0.5)


def _equivalent_stiffness(config) -> float:
    compliance = 1.0 / config.drawworks.line_stiffness_n_per_m
    for s in config.sections:
        area = math.pi / 4 * (s.outer_diameter_m ** 2 - s.inner_diameter_m ** 2)
        compliance += s.length_m / (s.young_modulus_pa * area)
    return 1.0 / compliance


def test_autodriller_step_response_on_wob_matches_the_linearised_loop():
    """
    WOB' = k_eq (v_b - ROP(WOB)), v_b = v_I + K_p e, v_I' = K_i e, e = WOB_sp - WOB.

    K_eq the line and the string's axial stiffness in series, ROP the bit-rock law linearised at
    the start. Within 5 % of the 20 kN step.
    """
    setpoint = 100e3
    config = load_config(overrides=QUIET + ['drawworks.mode=autodriller',
                                            f'drawworks.weight_on_bit_setpoint_n={setpoint}'])
    simulator = Simulator(config)
    rig = Rig(simulator)
    law = BitRockLaw.from_config(config.bit_rock)
    omega = config.operation.top_drive_speed_rad_per_s
    start = -config.bit_rock.static_weight_on_bit_n
    rop_0 = float(law.steady_rop(omega, -start))
    slope = float(law.steady_rop(omega, -start - 1.0)) - rop_0          # d ROP / d WOB
    stiffness = _equivalent_stiffness(config)
    kp = config.drawworks.autodriller_proportional_m_per_s_per_n
    ki = config.drawworks.autodriller_integral_m_per_s2_per_n

    def loop(_, x):
        wob, integral = x
        error = setpoint - wob
        return [stiffness * (integral + kp * error - rop_0 - slope * (wob - start)), ki * error]

    duration = 40.0
    times = np.arange(1, int(round(duration / simulator.dt)) + 1) * simulator.dt
    closed = solve_ivp(loop, (0, duration), [start, rop_0], t_eval=times, rtol=1e-9,
                       atol=1e-9).y[0]
    wob = []
    for _ in times:
        rig.step()
        wob.append(-simulator.last.weight_on_bit_n[0])
    wob = np.array(wob)
    assert closed[-1] - start > 0.9 * (setpoint - start)                 # it got there
    assert np.max(np.abs(wob - closed)) < 0.05 * (setpoint - start)


def test_axial_input_switches_at_run_time_without_a_jump():
    config = load_config(overrides=QUIET)
    simulator = Simulator(config)
    rig = Rig(simulator)
    assert rig.drawworks is None
    for _ in range(50):
        rig.step()
    before = simulator.observe().hook_load_n
    rig.set_axial_mode('autodriller')
    rig.set_weight_on_bit_setpoint(-simulator.last.weight_on_bit_n[0])
    rig.step()
    assert simulator.observe().hook_load_n == pytest.approx(before, abs=200.0)
    rig.set_axial_mode('hook_load')
    assert rig.drawworks is None
    held = rig.hook_load_command_n
    rig.step()
    assert simulator.observe().hook_load_n == held


def test_a_refused_step_puts_the_block_and_the_line_back():
    """
    When the simulator refuses a step, the rig's checkpoint puts the drawworks back.

    The block's position and velocity, the autodriller's integral and the hook load the line
    pulled: all as before the step (the refused step had moved them).
    """
    config = load_config(overrides=QUIET + ['drawworks.mode=autodriller',
                                            'drawworks.weight_on_bit_setpoint_n=100e3'])
    simulator = Simulator(config)
    rig = Rig(simulator)
    for _ in range(20):
        rig.step()
    before, hook = rig.drawworks.state.copy(), rig.hook_load_command_n
    checkpoint = rig.checkpoint()
    rig.inputs()
    assert rig.drawworks.state != before
    rig.restore(checkpoint)
    # A state the simulator cannot step (the drawworks reads the axial block only).
    simulator.state.q_rate[0, simulator.system.blocks['torsional'].columns] = np.nan
    with pytest.raises(SimulationDiverged):
        rig.step()
    assert rig.drawworks.state == before and rig.hook_load_command_n == hook
    assert rig.axial_mode.value == 'autodriller'


def test_the_block_accelerates_at_most_at_the_drums_limit():
    """
    A block-velocity step is followed at the configured acceleration, a ramp, not a jump.

    The block starts at the top's speed (bumpless), moves by a_max dt a step towards the
    command, then holds it exactly.
    """
    limit = 0.25
    config = load_config(overrides=QUIET + [f'drawworks.block_acceleration_max_m_per_s2={limit}'])
    simulator = Simulator(config)
    rig = Rig(simulator)
    rig.set_axial_mode('block_velocity')
    drawworks = rig.drawworks
    rig.set_block_velocity(-0.5)
    start = drawworks.state.block_velocity_m_per_s
    velocities = []
    for _ in range(int(round(3.0 / simulator.dt))):
        rig.step()
        velocities.append(drawworks.state.block_velocity_m_per_s)
    velocities = np.array(velocities)
    steps_to_reach = int(math.ceil((start + 0.5) / (limit * simulator.dt)))
    ramp = start - limit * simulator.dt * np.arange(1, steps_to_reach)
    np.testing.assert_allclose(velocities[:steps_to_reach - 1], ramp, rtol=0, atol=1e-12)
    assert np.all(velocities[steps_to_reach:] == -0.5)
    with pytest.raises(Exception, match='block_acceleration_max_m_per_s2'):
        load_config(overrides=['drawworks.block_acceleration_max_m_per_s2=0'])


def test_a_restart_from_a_safe_state_puts_the_block_where_the_line_holds_it():
    """
    After a member is restarted, the line pulls the hook load the safe state was built for.

    Without the reseat the block stays where it was and the line's stretch no longer matches
    the string: the next step's hook load jumps by k_line times the top's displacement.
    """
    config = load_config(overrides=QUIET + ['drawworks.mode=block_velocity',
                                            'drawworks.block_velocity_m_per_s=-0.3'])
    simulator = Simulator(config)
    rig = Rig(simulator)
    drawworks = rig.drawworks
    for _ in range(int(round(3.0 / simulator.dt))):      # lifting: the top has moved
        rig.step()
    rig.reset_members([0])
    assert line_hook_load_n(drawworks) == pytest.approx(
        rig.hook_load_command_n, rel=1e-9, abs=1.0 + drawworks.line_damping * abs(
            drawworks.top.now()[1] - drawworks.state.block_velocity_m_per_s))
    # The safe state is at rest off bottom while the block goes on rising: the next step's hook
    # load differs by the line's damping and one step of stretch, not k_line x 0.9 m (18 MN).
    held = rig.hook_load_command_n
    rig.step()
    speed = 0.3
    bound = (drawworks.line_damping * speed + drawworks.line_stiffness * speed * simulator.dt
             + 0.01 * held)
    assert abs(simulator.observe().hook_load_n - held) <= bound


def test_the_autodriller_feeds_line_and_never_hoists():
    """
    Switched on while the string moves up, the autodriller brakes the block to a stop.

    Its bumpless start is the top's speed (here upwards); with a WOB set-point of 0 off bottom
    the error is 0, and a PI alone would hoist the string at that speed forever (seen in the
    envelope sweep: 27 m up in 50 s). An autodriller feeds line: v_b >= 0.
    """
    config = load_config(overrides=QUIET + ['drawworks.block_acceleration_max_m_per_s2=0.5'])
    simulator = Simulator(config)
    rig = Rig(simulator)
    rig.set_axial_mode('block_velocity')
    drawworks = rig.drawworks
    rig.set_block_velocity(-0.5)
    for _ in range(int(round(3.0 / simulator.dt))):     # the string rises at 0.5 m/s
        rig.step()
    assert simulator.observe().hook_velocity_m_per_s[0] < -0.4
    rig.set_weight_on_bit_setpoint(0.0)
    rig.set_axial_mode('autodriller')
    assert drawworks.state.autodriller_integral_m_per_s == 0.0     # clamped: not -0.5 m/s
    velocities, integral = [], []
    for _ in range(int(round(3.0 / simulator.dt))):
        rig.step()
        velocities.append(drawworks.state.block_velocity_m_per_s)
        integral.append(drawworks.state.autodriller_integral_m_per_s)
    assert min(integral) >= 0.0
    assert velocities[0] < -0.4                         # bumpless: from the string's speed
    assert np.all(np.diff(velocities) >= -1e-12)        # braking, never hoisting harder
    assert velocities[-1] == 0.0


def test_the_autodriller_engaged_on_a_running_block_stays_within_its_feed_rate():
    """
    Engaged while the block still runs down at 0.2 m/s onto a bit that does not turn.

    The bumpless start is clamped to the ROP limit v_max, and so is the integral: the block
    slows to v_max and stops once the proportional action alone asks for less than nothing,
    so the WOB overshoots the set-point by at most v_max / K_p plus the line paid out while
    the block decelerates from 0.2 m/s to v_max. An integral started unclamped at 0.2 m/s
    would let this slow loop (natural period 2 pi / sqrt(k_eq K_i), about 130 s) feed the
    stopped bit to several times the set-point (900 kN at a 200 kN set-point).
    """
    config = load_config(overrides=QUIET + ['drawworks.mode=block_velocity'])
    simulator = Simulator(config)
    rig = Rig(simulator)
    drawworks = rig.drawworks
    rig.set_top_drive_speed(0.0)
    for _ in range(int(round(5.0 / simulator.dt))):        # the bit stops on bottom
        rig.step()
    start = 0.2
    rig.set_block_velocity(start)
    while drawworks.state.block_velocity_m_per_s < start:
        rig.step()
    setpoint = 200e3
    rig.set_weight_on_bit_setpoint(setpoint)
    rig.set_axial_mode('autodriller')
    feed_max = config.drawworks.autodriller_feed_rate_max_m_per_s
    assert drawworks.state.autodriller_integral_m_per_s == feed_max   # clamped: not 0.2 m/s
    wob, block, integral = [], [], []
    for _ in range(int(round(40.0 / simulator.dt))):
        rig.step()
        wob.append(-simulator.last.weight_on_bit_n[0])
        block.append(drawworks.state.block_velocity_m_per_s)
        integral.append(drawworks.state.autodriller_integral_m_per_s)
    assert 0.0 <= min(integral) and max(integral) <= feed_max
    kp = config.drawworks.autodriller_proportional_m_per_s_per_n
    deceleration = config.drawworks.block_acceleration_max_m_per_s2
    braking = (start ** 2 - feed_max ** 2) / (2 * deceleration) * _equivalent_stiffness(config)
    assert np.max(wob) <= setpoint + feed_max / kp + braking
    assert np.max(wob) > setpoint                          # it did overshoot: the bound matters
    assert max(block[int(round(2.0 / simulator.dt)):]) <= feed_max
    assert block[-1] == 0.0 and wob[-1] > setpoint         # holds, never hoists
    for bad in ('0', '-0.01', '10'):
        with pytest.raises(Exception, match='autodriller_feed_rate_max_m_per_s'):
            load_config(overrides=[f'drawworks.autodriller_feed_rate_max_m_per_s={bad}'])


def test_the_autodriller_integral_is_held_within_its_clamp():
    """
    The integral v_I itself, step by step: v_I <- clip(v_I + K_i dt e, 0, v_max).

    e = WOB_sp - WOB of the last step, v_max the configured feed-rate limit; engaged on a
    block running down at 0.2 m/s the integral starts at v_max (bumpless, clamped). A stopped
    bit is fed towards 400 kN (e > 0 throughout: the unclamped integral rises past v_max),
    then the set-point drops to 0 (e < 0 throughout: it would fall below 0). The state is
    read off the drawworks after every step, never through the block's velocity (which the
    target's own clamp limits whatever the integral does).
    """
    config = load_config(overrides=QUIET + ['drawworks.mode=block_velocity',
                                            'drawworks.autodriller_integral_m_per_s2_per_n=5e-8'])
    settings = config.drawworks
    ki, feed_max = settings.autodriller_integral_m_per_s2_per_n, \
        settings.autodriller_feed_rate_max_m_per_s
    simulator = Simulator(config)
    rig = Rig(simulator)
    drawworks = rig.drawworks
    dt = simulator.dt
    rig.set_top_drive_speed(0.0)
    for _ in range(int(round(3.0 / dt))):                     # the bit stops on bottom
        rig.step()
    rig.set_block_velocity(0.2)
    while drawworks.state.block_velocity_m_per_s < 0.2:
        rig.step()
    rig.set_weight_on_bit_setpoint(400e3)
    rig.set_axial_mode('autodriller')
    assert drawworks.state.autodriller_integral_m_per_s == feed_max      # not 0.2 m/s
    expected = free = feed_max
    integral, unclamped = [], []
    for setpoint, seconds in ((400e3, 4.0), (0.0, 6.0)):
        rig.set_weight_on_bit_setpoint(setpoint)
        for _ in range(int(round(seconds / dt))):
            error = setpoint - (-float(simulator.last.weight_on_bit_n[0]))
            assert error > 0 if setpoint else error < 0
            expected = min(max(expected + ki * dt * error, 0.0), feed_max)
            free += ki * dt * error
            rig.step()
            integral.append(drawworks.state.autodriller_integral_m_per_s)
            assert integral[-1] == pytest.approx(expected, rel=1e-12, abs=1e-15)
            unclamped.append(free)
    integral, unclamped = np.array(integral), np.array(unclamped)
    assert np.all((0.0 <= integral) & (integral <= feed_max))
    assert np.max(unclamped) > 2 * feed_max and np.min(unclamped) < -feed_max
    assert np.sum(integral == feed_max) > 100 and np.sum(integral == 0.0) > 100


# -- the drum's brake under the hook force -----------------------------------------------------

def _pick_up_and_drop(brake: str):
    """
    Hook-load mode: 250 kN of WOB released to the string's weight + 50 kN, then dropped.

    10 s at the weight + 50 kN (the string leaves the bottom), then 20 s at the weight -
    250 kN; returns (time s, top's axial velocity m/s (down > 0), applied hook load N, bit
    above the hole m) per step, and the commands.
    """
    config = load_config(None, QUIET + ['integration.time_step_s=0.005',
                                        f'drawworks.block_speed_max_m_per_s={brake}'])
    simulator = Simulator(config)
    rig = Rig(simulator)
    weight = rig.hook_load_command_n - config.bit_rock.static_weight_on_bit_n
    rig.set_hook_load(weight - 250e3)
    for _ in range(1000):
        rig.step()
    rows = []
    for seconds, command in ((10.0, weight + 50e3), (20.0, weight - 250e3)):
        rig.set_hook_load(command)
        for _ in range(int(round(seconds / simulator.dt))):
            rig.step()
            o = simulator.observe(detailed=1)
            assert np.ndim(o.hook_load_n) == 0                # one member: one hook load
            rows.append((simulator.time_s, float(o.hook_velocity_m_per_s[0]),
                         float(o.hook_load_n),
                         float(o.hole_depth_m[0] - o.bit_depth_m[0]), command))
    return np.array(rows)


def test_the_drums_brake_holds_the_top_to_the_block_speed_and_lets_the_rest_through():
    """
    A hook force that would fling the string is held to the block's top speed (1 m/s).

    Released from 250 kN of WOB to 50 kN above its weight, the bare hook force of the paper
    throws the string up at several m/s and, dropped 250 kN below its weight, onto the rock at
    several m/s (measured 16 and 14 m/s with two lateral modes and the full axial model). With
    the brake the top never moves faster than 1 m/s (to the prediction's 0.3 % from the last
    step's bit force); the string still lifts off metres and lands. Wherever the brake does not
    act the applied hook load is the command to the last digit.
    """
    braked = _pick_up_and_drop('1.0')
    bare = _pick_up_and_drop('null')
    assert np.max(np.abs(bare[:, 1])) > 5.0
    assert np.max(np.abs(braked[:, 1])) <= 1.0 * 1.005
    assert np.max(braked[:, 3]) > 3.0 and braked[-1, 3] <= 0.0        # lifted off, landed
    held = np.abs(braked[:, 1]) > 0.999
    free = np.abs(braked[:, 1]) < 0.9
    assert held.sum() > 1000 and free.sum() > 1000
    assert np.array_equal(braked[free, 2], braked[free, 4])
    # Rising, the brake adds to the command; falling, it takes from it (a hook only pulls).
    rising, falling = held & (braked[:, 1] < 0), held & (braked[:, 1] > 0)
    assert np.all(braked[falling, 2] >= braked[falling, 4])
    assert np.all(braked[rising, 2] <= braked[rising, 4])
    assert np.mean(braked[falling, 2] > braked[falling, 4]) > 0.9
    assert np.mean(braked[rising, 2] < braked[rising, 4]) > 0.9
