"""
Stick-slip controllers on the dynamic top drive (docs/DRIVES.md, "Stick-slip controllers").

The reflection of a torsional pulse at the top, measured at a station of a long uniform pipe.
"""
from __future__ import annotations

import math

import pytest
import numpy as np

from drill_twin.config import load_config
from drill_twin.rig.controllers import Impedance, SoftTorque, Stiff, make_controller
from drill_twin.integrator.simulator import Simulator
from drill_twin.rig.rig import Rig
from drill_twin.rig.top_drive import (DynamicTopDrive, KinematicTopDrive, TopDriveMode,
                                      characteristic_impedance)
from drill_twin.analysis.torsional_pulse import reflection_coefficient, upward_pulse

PIPE = """
sections:
  - name: drill_pipe
    kind: drill_pipe
    length_m: 4000.0
    outer_diameter_m: 0.127
    inner_diameter_m: 0.095
    elements: 100
    young_modulus_pa: 210.0e9
    density_kg_per_m3: 7850.0
    poisson_ratio: 0.29
    shear_correction_factor: 0.8571428571428571
stabilizers: []
output:
  stations_m: [2000.0]
  record_interval_s: 0.01
"""
LINEAR = ['physics.' + name + '=false' for name in (
    'gravity', 'prestress', 'fluid', 'stabilizers', 'contact', 'bit_rock', 'kinetic_coupling',
    'finite_strain')] + [
    'damping.mass_coefficient_per_s=0', 'damping.stiffness_coefficient_s=0',
    'reduced_basis.lateral_modes=0', 'reduced_basis.torsional_modes=60',
    'reduced_basis.axial_modes=0', 'initial_conditions.lateral_deflection_m=0',
    'top_drive.mode=dynamic']


def test_the_characteristic_impedance_is_the_pipes(default_config):
    pipe = default_config.sections[0]
    polar = math.pi / 32 * (0.127 ** 4 - 0.095 ** 4)
    shear = 6 / 7 * 210e9 / (2 * 1.29)
    assert characteristic_impedance(default_config) == pytest.approx(
        polar * math.sqrt(7850 * shear), rel=1e-12)
    assert pipe.name == 'drill_pipe'


def test_the_configuration_picks_the_controller(default_config):
    from drill_twin.model.reduced_system import build_reduced_system
    from drill_twin.modal.reduced_basis import modal_analysis as analysis
    config = load_config(overrides=['reduced_basis.lateral_modes=0'])
    model, _, basis = analysis(config)
    system = build_reduced_system(model, basis)
    assert isinstance(make_controller(config, system), Stiff)
    for name, kind in (('soft_torque', SoftTorque), ('impedance', Impedance)):
        chosen = load_config(overrides=[f'top_drive.controller={name}',
                                        'top_drive.impedance_nm_s_per_rad=123'])
        controller = make_controller(chosen, system)
        assert isinstance(controller, kind) and controller.impedance == 123.0


@pytest.mark.parametrize('controller, low, high', [('stiff', 0.9, 1.1),
                                                   ('impedance', 0.0, 0.1)])
def test_reflection_of_a_torsional_pulse_at_the_top(tmp_path, controller, low, high):
    """
    Reflection |r| about 1 at a stiff drive, below 0.1 at a matched damper.

    A fixed end inverts the wave; below 0.1 when the drive is a damper matched to the pipe's
    impedance.
    """
    path = tmp_path / 'pipe.yaml'
    path.write_text(PIPE)
    config = load_config(path, overrides=LINEAR + [f'top_drive.controller={controller}'])
    section = config.sections[0]
    wave_speed = math.sqrt(section.shear_correction_factor * section.shear_modulus_pa
                           / section.density_kg_per_m3)
    simulator = Simulator(config)
    rig = Rig(simulator)
    q, rate = simulator.state.q.copy(), simulator.state.q_rate.copy()
    columns = simulator.system.blocks['torsional'].columns
    q[:, columns], rate[:, columns] = upward_pulse(simulator.system, 3000.0, 400.0, 0.5,
                                                   wave_speed)
    simulator.reset(q, rate)
    times, speeds = [], []
    for _ in range(int(round(2.4 / simulator.dt))):
        rig.step()
        times.append(simulator.time_s)
        speeds.append(simulator.observe().station_spin_rate_rad_per_s[0, 0, 0])
    speeds = np.array(speeds)
    assert np.max(speeds - speeds[0]) == pytest.approx(0.5, rel=0.05)    # the incident pulse
    r = reflection_coefficient(np.array(times), speeds, 2000.0 / wave_speed)
    assert low <= abs(r) <= high


def test_top_drive_mode_and_controller_switch_at_run_time_without_a_jump():
    simulator = Simulator(load_config(overrides=[
        'physics.contact=false', 'physics.kinetic_coupling=false',
        'physics.finite_strain=false', 'reduced_basis.lateral_modes=0',
        'initial_conditions.lateral_deflection_m=0', 'initial_conditions.steady_twist=true']))
    rig = Rig(simulator)
    for _ in range(20):
        rig.step()
    speed = rig.top_drive.speed_rad_per_s
    rig.set_top_drive_mode('dynamic', 'impedance')
    drive = rig.top_drive
    assert isinstance(drive, DynamicTopDrive) and isinstance(drive.controller, Impedance)
    assert rig.top_drive_mode is TopDriveMode.DYNAMIC and rig.commands.controller == 'impedance'
    assert drive.state.motor_torque_nm == pytest.approx(simulator.observe().top_torque_nm[0])
    rig.step()
    assert drive.speed_rad_per_s == pytest.approx(speed, abs=1e-3)
    rig.set_torque_limit(5e3)
    assert drive.state.torque_limit_nm == 5e3
    with pytest.raises(ValueError):
        rig.set_torque_limit(-1.0)
    with pytest.raises(ValueError, match='hydraulic'):
        rig.set_top_drive_mode('hydraulic')
    rig.set_top_drive_mode('kinematic')
    assert type(rig.top_drive) is KinematicTopDrive
    rig.step()
    assert rig.top_drive.speed_rad_per_s == pytest.approx(speed, abs=2e-2)
    rig.set_top_drive_mode(TopDriveMode.DYNAMIC)             # the torque limit was kept
    assert rig.top_drive.state.torque_limit_nm == 5e3
    assert isinstance(rig.top_drive.controller, Impedance)


def _system(config):
    from drill_twin.model.reduced_system import build_reduced_system
    from drill_twin.modal.reduced_basis import modal_analysis
    model, _, basis = modal_analysis(config)
    return build_reduced_system(model, basis)


def test_linear_stability_with_one_mode_is_the_closed_form():
    """
    One mass-normalised torsional mode at the imposed speed.

    S^2 + (c_1 + phi_b^2 D) s + w_1^2 = 0, growth rate -(c_1 + phi_b^2 D) / 2 when it
    oscillates.
    """
    from drill_twin.analysis.drive_stability import growth_rate_per_s
    config = load_config(overrides=['reduced_basis.lateral_modes=0',
                                    'reduced_basis.torsional_modes=1'])
    system = _system(config)
    columns = system.blocks['torsional'].columns
    c1 = float(system.damping[columns, columns][0, 0])
    phi = float(system.blocks['torsional'].shapes[system.bit_node][0])
    for slope in (-300.0, -100.0, 200.0):
        expected = -(c1 + phi ** 2 * slope) / 2
        assert growth_rate_per_s(config, system, 'kinematic', slope) == pytest.approx(
            expected, rel=1e-9)


def test_a_stiff_drive_is_the_kinematic_one_and_the_torque_feedback_stabilises_100_kn():
    """
    At the paper's point soft_torque and impedance make the stick-slip decay.

    At the paper's point (velocity weakening D = -179 N m s/rad) the kinematic and stiff
    drives grow (stick-slip) at the same rate; soft_torque and impedance make it decay.
    """
    from drill_twin.analysis.drive_stability import (bit_torque_slope_nm_s_per_rad,
                                                     growth_rate_per_s)
    config = load_config(overrides=['reduced_basis.lateral_modes=0'])
    system = _system(config)
    slope = bit_torque_slope_nm_s_per_rad(config, config.operation.top_drive_speed_rad_per_s,
                                          100e3)
    assert slope < 0
    rates = {d: growth_rate_per_s(config, system, d, slope)
             for d in ('kinematic', 'stiff', 'soft_torque', 'impedance')}
    assert rates['kinematic'] > 0.1
    assert rates['stiff'] == pytest.approx(rates['kinematic'], rel=0.02)
    assert rates['soft_torque'] < 0 and rates['impedance'] < 0
