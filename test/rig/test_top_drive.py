"""
The dynamic top drive against closed forms (docs/DRIVES.md, "The top drive").

The string's torque predicted one step ahead, the torsional eigenfrequencies of the string with
the drive's inertia and the PI loop's stiffness at the top, the PI step response on a rigid
string, the torque limit, and the energy balance over a stick-slip cycle.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.signal import find_peaks

from drill_twin.analysis.drive_energy import EnergyMeter
from drill_twin.config import ConfigError, load_config
from drill_twin.integrator.simulator import SimulationDiverged, Simulator
from drill_twin.rig.drawworks import DrawworksState, FollowedBlockState
from drill_twin.rig.rig import Rig, RigCommands
from drill_twin.rig.top_drive import (DynamicState, DynamicTopDrive, FollowedState,
                                      KinematicState, KinematicTopDrive, TopDriveMode)

LINEAR = ['physics.' + name + '=false' for name in (
    'gravity', 'prestress', 'fluid', 'stabilizers', 'contact', 'bit_rock', 'kinetic_coupling',
    'finite_strain')] + [
    'damping.mass_coefficient_per_s=0', 'damping.stiffness_coefficient_s=0',
    'reduced_basis.lateral_modes=0', 'reduced_basis.axial_modes=1',
    'initial_conditions.lateral_deflection_m=0', 'top_drive.mode=dynamic']
"""A purely torsional, undamped string with a dynamic top drive."""


def _rig(overrides) -> Rig:
    return Rig(Simulator(load_config(overrides=overrides)))


def _string_polar_inertia_kg_m2(config) -> float:
    """J_s = sum(rho I_p L) of the sections, I_p = pi (D_o^4 - D_i^4) / 32 (dry, no bit)."""
    return sum(s.density_kg_per_m3 * math.pi / 32
               * (s.outer_diameter_m ** 4 - s.inner_diameter_m ** 4) * s.length_m
               for s in config.sections)


def shaft_frequencies_hz(config, inertia, spring, f_max_hz, bit_inertia=0.0):
    """
    Return the torsional eigenfrequencies (Hz) of the sections of ``config`` as shafts.

    The sections as continuous shafts (stiffness k_s G I_p, MODEL.md), an inertia ``inertia``
    (kg m^2) on a spring ``spring`` (N m/rad) to ground at the top and ``bit_inertia`` at the
    free bit: the roots of the transfer-matrix frequency equation, bracketed on a fine grid.
    """
    def bit_residual(omega):
        theta, torque = 1.0, spring - omega ** 2 * inertia
        for s in config.sections:
            polar = math.pi / 32 * (s.outer_diameter_m ** 4 - s.inner_diameter_m ** 4)
            shear = s.shear_correction_factor * s.shear_modulus_pa
            wave = omega * math.sqrt(s.density_kg_per_m3 / shear)
            gamma = shear * polar * wave
            c, sn = math.cos(wave * s.length_m), math.sin(wave * s.length_m)
            theta, torque = c * theta + sn / gamma * torque, -gamma * sn * theta + c * torque
        return torque - omega ** 2 * bit_inertia * theta

    grid = np.linspace(1e-3, 2 * math.pi * f_max_hz, 20000)
    values = np.array([bit_residual(w) for w in grid])
    roots = [brentq(bit_residual, grid[i], grid[i + 1], xtol=1e-14)
             for i in np.flatnonzero(np.sign(values[:-1]) != np.sign(values[1:]))]
    return np.array(roots) / (2 * math.pi)


def pencil_frequencies_hz(signal, dt, order):
    """Frequencies (Hz) of a sum of undamped sinusoids by the matrix-pencil method."""
    n = signal.size
    rows = n // 3
    hankel = np.array([signal[i:i + rows + 1] for i in range(n - rows)])
    _, _, vt = np.linalg.svd(hankel, full_matrices=False)
    v = vt[:order].T
    poles = np.linalg.eigvals(np.linalg.pinv(v[:-1]) @ v[1:])
    frequency = np.abs(np.angle(poles)) / (2 * math.pi * dt)
    return np.unique(np.round(np.sort(frequency[frequency > 1e-6]), 9))


def test_defaults_keep_the_papers_kinematic_drive(default_config):
    assert default_config.top_drive.mode == 'kinematic'
    assert default_config.top_drive.controller == 'stiff'
    assert default_config.drawworks.mode == 'hook_load'
    rig = Rig(Simulator(load_config(overrides=[
        'reduced_basis.lateral_modes=0', 'initial_conditions.lateral_deflection_m=0'])))
    assert type(rig.top_drive) is KinematicTopDrive
    assert rig.top_drive_mode is TopDriveMode.KINEMATIC and rig.drawworks is None


@pytest.mark.parametrize('item, key', [
    ('top_drive.inertia_kg_m2=-1', 'top_drive.inertia_kg_m2'),
    ('top_drive.mode=hydraulic', 'top_drive.mode'),
    ('top_drive.controller=fuzzy', 'top_drive.controller'),
    ('top_drive.torque_limit_nm=0', 'top_drive.torque_limit_nm'),
    ('top_drive.proportional_gain_nm_s_per_rad=1e12', 'top_drive.proportional_gain_nm_s_per_rad'),
    ('drawworks.mode=winch', 'drawworks.mode'),
    ('drawworks.line_stiffness_n_per_m=0', 'drawworks.line_stiffness_n_per_m'),
])
def test_bad_drive_values_are_refused_naming_the_key(item, key):
    with pytest.raises(ConfigError) as error:
        load_config(overrides=[item])
    message = str(error.value)
    assert key in message and '\n' not in message


def test_the_predicted_string_torque_is_the_simulators_for_a_linear_string():
    """
    The torsional block is linear here.

    The one-step predictor must replay the simulator's Newmark step exactly (the coupling then
    has no lag).
    """
    rig = _rig(LINEAR + ['reduced_basis.torsional_modes=6',
                         'top_drive.proportional_gain_nm_s_per_rad=0',
                         'top_drive.integral_gain_nm_per_rad=3e4'])
    simulator, drive = rig.simulator, rig.top_drive
    assert isinstance(drive, DynamicTopDrive)
    rig.set_top_drive_speed(drive.speed_rad_per_s + 1.0)
    largest = 0.0
    for _ in range(200):
        rig.step()
        observed = simulator.observe().top_torque_nm[0]
        assert drive.state.predicted_string_torque_nm == pytest.approx(observed, rel=1e-9,
                                                                       abs=1e-6)
        assert drive.string.measured() == pytest.approx(observed, rel=1e-12, abs=1e-9)
        largest = max(largest, abs(observed))
    assert largest > 100.0                                    # the string was loaded


def test_eigenfrequencies_with_the_drive_inertia_and_pi_stiffness_match_the_shaft():
    """
    An integral-only loop is a torsional spring K_i to the set-point angle.

    The string with J_d on that spring at the top, free at the bit. The frequencies measured
    from the simulated free response (matrix pencil on the top speed) match the continuous
    two-section shaft within 0.5 %.
    """
    inertia, spring = 2000.0, 3.0e4
    rig = _rig(LINEAR + ['reduced_basis.torsional_modes=12',
                         'top_drive.proportional_gain_nm_s_per_rad=0',
                         f'top_drive.integral_gain_nm_per_rad={spring}',
                         f'top_drive.inertia_kg_m2={inertia}'])
    expected = shaft_frequencies_hz(rig.config, inertia, spring, 1.5)
    assert expected.size == 3
    start = rig.top_drive.speed_rad_per_s
    rig.set_top_drive_speed(start + 1.0)
    samples = []
    for k in range(2400):
        rig.step()
        if k % 4 == 3:
            samples.append(rig.top_drive.speed_rad_per_s - start - 1.0)
    measured = pencil_frequencies_hz(np.array(samples), 4 * rig.simulator.dt, 10)
    assert measured[:3] == pytest.approx(expected, rel=5e-3)


def _rigid_string(dt, kp, ki, inertia):
    return _rig(LINEAR + ['reduced_basis.torsional_modes=0', 'reduced_basis.axial_modes=0',
                          f'integration.time_step_s={dt}',
                          f'top_drive.proportional_gain_nm_s_per_rad={kp}',
                          f'top_drive.integral_gain_nm_per_rad={ki}',
                          f'top_drive.inertia_kg_m2={inertia}'])


def test_pi_step_response_on_a_rigid_string_matches_the_closed_form():
    """
    J e'' + K_p e' + K_i e = 0 for the speed error e, J = J_d + J_s.

    The drive's backward-Euler step converges to it at first order.
    """
    kp, ki, inertia, step = 2.0e4, 5.0e4, 2000.0, 1.0
    errors = []
    for dt in (0.005, 0.0025):
        rig = _rigid_string(dt, kp, ki, inertia)
        total = inertia + _string_polar_inertia_kg_m2(rig.config)
        assert rig.simulator.system.blocks['torsional'].shapes.shape[1] == 0
        start = rig.top_drive.speed_rad_per_s
        rig.set_top_drive_speed(start + step)
        times, speeds = [], []
        for _ in range(int(round(3.0 / dt))):
            rig.step()
            times.append(rig.simulator.time_s)
            speeds.append(rig.top_drive.speed_rad_per_s)
        roots = np.roots([total, kp, ki])
        amplitudes = np.linalg.solve([[1, 1], roots], [step, -kp * step / total])
        error = np.real(amplitudes @ np.exp(np.outer(roots, times)))
        exact = start + step - error
        assert np.max(exact) - start - step > 0.1 * step          # an overshoot to resolve
        errors.append(np.max(np.abs(np.array(speeds) - exact)) / step)
    assert errors[0] < 0.01
    assert errors[0] / errors[1] == pytest.approx(2.0, rel=0.1)


def test_the_motor_torque_is_limited_and_the_integral_does_not_wind_up():
    limit = 5.0e3
    rig = _rig(LINEAR + ['reduced_basis.torsional_modes=0', 'reduced_basis.axial_modes=0',
                         f'top_drive.torque_limit_nm={limit}'])
    drive = rig.top_drive
    total = rig.config.top_drive.inertia_kg_m2 + _string_polar_inertia_kg_m2(rig.config)
    start = drive.speed_rad_per_s
    rig.set_top_drive_speed(start + 5.0)
    rig.step()
    assert drive.state.saturated and drive.state.motor_torque_nm == limit
    assert (drive.speed_rad_per_s - start) / rig.simulator.dt == pytest.approx(limit / total,
                                                                               rel=1e-9)
    integral = drive.state.integral_torque_nm
    for _ in range(100):
        rig.step()
    assert drive.state.saturated and drive.state.integral_torque_nm == integral


def test_energy_balance_over_a_stick_slip_cycle():
    """
    Motor work + work of the bit = change of torsional energy + dissipation.

    The change of drive and string torsional energy plus dissipation, over one stick-slip
    cycle of the paper's string (lateral motion off), within 1 % of the motor work.
    """
    rig = _rig([
        'physics.contact=false', 'physics.kinetic_coupling=false',
        'physics.finite_strain=false', 'reduced_basis.lateral_modes=0',
        'initial_conditions.lateral_deflection_m=0', 'top_drive.mode=dynamic'])
    simulator = rig.simulator
    meter = EnergyMeter(rig)
    meter.start()
    speed, budgets = [], []
    for _ in range(int(round(9.5 / simulator.dt))):
        rig.step()
        meter.record()
        speed.append(simulator.last.bit_speed_rad_per_s[0])
        budgets.append((meter.budget.motor_work_j, meter.budget.residual_j))
    speed, budgets = np.array(speed), np.array(budgets)
    peaks, _ = find_peaks(speed, distance=int(2.0 / simulator.dt))
    first, second = peaks[-2], peaks[-1]
    cycle = speed[first:second + 1]
    assert (cycle.max() - cycle.min()) / (2 * cycle.mean()) > 0.4        # stick-slip
    motor = budgets[second, 0] - budgets[first, 0]
    residual = budgets[second, 1] - budgets[first, 1]
    assert motor > 1e4
    assert abs(residual) < 0.01 * motor


def test_the_rig_takes_the_configured_drive_and_a_refused_step_puts_it_back():
    """
    Built from a config with ``top_drive.mode: dynamic`` the rig drives the dynamic drive.

    When the simulator refuses a step (SimulationDiverged), the rig's checkpoint puts the
    drive back as it was before the step: speed, PI integral, motor torque.
    """
    rig = _rig(LINEAR + ['reduced_basis.torsional_modes=2'])
    drive = rig.top_drive
    assert isinstance(drive, DynamicTopDrive) and rig.top_drive_mode is TopDriveMode.DYNAMIC
    start = drive.speed_rad_per_s
    rig.set_top_drive_speed(start + 0.1)                      # below the torque limit
    rig.step()
    assert not drive.state.saturated
    before = drive.state.copy()
    checkpoint = rig.checkpoint()
    rig.inputs()                                              # a step that will be discarded
    assert drive.state.integral_torque_nm != before.integral_torque_nm
    rig.restore(checkpoint)
    assert rig.top_drive is drive and drive.state == before
    # A state the simulator cannot step (the drive reads the torsional block only).
    rig.simulator.state.q_rate[0, rig.simulator.system.blocks['axial'].columns] = np.nan
    with pytest.raises(SimulationDiverged):
        rig.step()                                            # refused: the drive is put back
    assert drive.state == before


@pytest.mark.parametrize('kind', [KinematicState, FollowedState, DynamicState, DrawworksState,
                                  FollowedBlockState, RigCommands])
def test_a_checkpoints_copy_of_a_state_keeps_every_field(kind):
    """Every field of the rig's state dataclasses survives ``copy()`` (what a checkpoint keeps)."""
    fields = dataclasses.fields(kind)
    values = [float(k + 1) for k in range(len(fields))]
    state = kind(*values)
    copied = state.copy()
    assert copied is not state
    assert [getattr(copied, f.name) for f in fields] == values
