"""Linear stability of steady drilling, checked against closed forms and the simulation."""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.optimize import brentq
from threadpoolctl import threadpool_limits

from drill_twin.config import load_config
from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.analysis.linear_stability import AxialTorsionalLinearisation, stability_grid
from drill_twin.model.reduced_system import build_reduced_system
from drill_twin.integrator.simulator import Simulator
from drill_twin.analysis.steady_drilling import (SteadyDrilling, hook_load_for,
                                                 steady_coordinates, string_weight_n,
                                                 under_hook_load)
from drill_twin.modal.reduced_basis import modal_analysis

# A coarse string whose axial-torsional motion is linear but for the bit-rock law.
COARSE = ('reduced_basis.lateral_modes=0', 'sections.drill_pipe.elements=8',
          'sections.drill_collar.elements=4', 'physics.contact=false',
          'physics.finite_strain=false', 'physics.kinetic_coupling=false',
          'integration.time_step_s=0.02')


def _system(*overrides):
    config = load_config(None, COARSE + overrides)
    model, _, basis = modal_analysis(config)
    return config, build_reduced_system(model, basis)


@pytest.fixture(scope='module')
def one_mode():
    return _system('reduced_basis.torsional_modes=1', 'reduced_basis.axial_modes=0')


def test_without_the_bit_every_mode_has_its_rayleigh_damping():
    """
    Without the bit (J = 0) every mode has its Rayleigh damping.

    Each elastic mode (pulsation w from the modal solver) has the roots of s^2 + (alpha + beta
    w^2) s + w^2; the rigid axial mode's rate decays at alpha.
    """
    config, system = _system('reduced_basis.torsional_modes=3', 'reduced_basis.axial_modes=2')
    alpha = config.damping.mass_coefficient_per_s
    beta = config.damping.stiffness_coefficient_s
    linearisation = AxialTorsionalLinearisation(system)
    eigenvalues = np.linalg.eigvals(linearisation.state_matrix(np.zeros((2, 2))))
    columns = np.r_[np.arange(system.blocks['axial'].columns.start,
                              system.blocks['axial'].columns.stop),
                    np.arange(system.blocks['torsional'].columns.start,
                              system.blocks['torsional'].columns.stop)]
    expected = []
    for column in columns:
        index = system.basis_columns[column]
        if system.basis.rigid[index]:
            expected.append(-alpha + 0j)
            continue
        w = 2 * np.pi * system.basis.frequency_hz[index]
        c = alpha + beta * w * w
        root = np.sqrt(w * w - c * c / 4)
        expected += [-c / 2 + 1j * root, -c / 2 - 1j * root]
    key = (lambda z: (round(z.imag, 6), z.real))
    assert_allclose(sorted(eigenvalues, key=key), sorted(expected, key=key), rtol=1e-7,
                    atol=1e-9)


def _resisting_torque_slope(law, omega, wob, h=1e-4):
    """dT/domega at constant WOB, T = -t_bit along the steady curve (central difference)."""
    return -(law.steady_torque(omega + h, -wob) - law.steady_torque(omega - h, -wob)) / (2 * h)


def _closed_form(system, config, law, omega, wob):
    """Growth rate and frequency of s^2 + (c1 + phi_b^2 dT/domega) s + w1^2 = 0."""
    torsion = system.blocks['torsional']
    column = torsion.columns.start
    w1 = 2 * np.pi * system.basis.frequency_hz[system.basis_columns[column]]
    c1 = (config.damping.mass_coefficient_per_s
          + config.damping.stiffness_coefficient_s * w1 * w1)
    phi = torsion.shapes[system.bit_node][0]
    damping = c1 + phi * phi * _resisting_torque_slope(law, omega, wob)
    roots = np.roots([1.0, damping, w1 * w1])
    least = roots[np.argmax(roots.real)]
    return least.real, abs(least.imag) / (2 * np.pi), c1, phi


@pytest.mark.parametrize('omega, wob', [(3.0, 100e3), (5.215, 100e3), (10.0, 100e3),
                                        (6.0, 200e3), (15.0, 60e3), (20.0, 250e3)])
def test_one_torsional_mode_follows_the_velocity_weakening_closed_form(one_mode, omega, wob):
    """
    The lumped pendulum.

    Growth = -(c1 + phi_b^2 dT/domega|_WOB) / 2 (module docstring); the quasi-static axial
    motion is the only approximation: the axial eigenvalue is about -150 to -210 1/s against |s|
    ~ 1.4 1/s for the torsional pair, so the closed form is good to about |s| / 150 ~ 1 %.
    """
    config, system = one_mode
    law = BitRockLaw.from_config(config.bit_rock)
    result = AxialTorsionalLinearisation(system).at(SteadyDrilling.of(law, omega, wob))
    growth, frequency, c1, _ = _closed_form(system, config, law, omega, wob)
    assert_allclose(result.growth_rate_per_s, growth, rtol=0.02, atol=0.01 * c1)
    assert_allclose(result.frequency_hz, frequency, rtol=0.01)


def test_the_boundary_is_where_velocity_weakening_beats_the_damping(one_mode):
    """
    At 100 kN the resisting torque peaks near 4 rad/s and weakens beyond.

    The closed form puts the boundary where -phi_b^2 dT/domega = c1; the linearisation changes
    sign there.
    """
    config, system = one_mode
    law = BitRockLaw.from_config(config.bit_rock)
    wob = 100e3
    _, _, c1, phi = _closed_form(system, config, law, 5.0, wob)
    boundary = brentq(lambda w: c1 + phi * phi * _resisting_torque_slope(law, w, wob), 3.5, 6.0)
    linearisation = AxialTorsionalLinearisation(system)
    below = linearisation.at(SteadyDrilling.of(law, boundary - 0.02, wob))
    above = linearisation.at(SteadyDrilling.of(law, boundary + 0.02, wob))
    assert below.stable and not above.stable
    assert _resisting_torque_slope(law, boundary, wob) < 0          # velocity weakening


def test_stability_grid_matches_pointwise_results(one_mode):
    config, system = one_mode
    law = BitRockLaw.from_config(config.bit_rock)
    growth, frequency = stability_grid(system, law, [3.0, 8.0], [60e3, 150e3])
    single = AxialTorsionalLinearisation(system).at(SteadyDrilling.of(law, 8.0, 150e3))
    assert growth.shape == (2, 2)
    assert growth[1, 1] == single.growth_rate_per_s and frequency[1, 1] == single.frequency_hz


def test_steady_coordinates_are_an_equilibrium_of_the_simulation():
    """
    Started from steady drilling with no perturbation, the simulated bit stays there.

    It keeps the top's speed, the law's ROP and the WOB set by the hook load (the hook-load
    balance).
    """
    config, system = _system('reduced_basis.torsional_modes=2', 'reduced_basis.axial_modes=2')
    law = BitRockLaw.from_config(config.bit_rock)
    omega, wob = 3.0, 150e3                                  # linearly stable
    hook = hook_load_for(system, wob)
    assert hook == pytest.approx(string_weight_n(system) - wob)
    steady = under_hook_load(system, law, omega, hook)
    mesh = system.model.mesh
    string_mass = np.sum(mesh.density_kg_per_m3 * mesh.area_m2 * mesh.length_m)
    drag = config.damping.mass_coefficient_per_s * string_mass * steady.rop_m_per_s
    assert_allclose(wob - steady.weight_on_bit_n, drag, rtol=1e-6)   # alpha M ROP
    point = _point_config(config, omega, hook)
    with threadpool_limits(limits=1, user_api='blas'):
        simulator = Simulator(point, system=system)
        simulator.reset(*steady_coordinates(system, steady, hook, simulator.state.q,
                                            simulator.state.q_rate))
        for _ in range(50):
            simulator.step()
    last = simulator.last
    assert_allclose(last.bit_speed_rad_per_s[0], omega, atol=1e-8)
    assert_allclose(last.rop_m_per_s[0], steady.rop_m_per_s, rtol=1e-8)
    assert_allclose(-last.weight_on_bit_n[0], steady.weight_on_bit_n, rtol=1e-9)


def _point_config(config, omega, hook):
    import dataclasses
    operation = dataclasses.replace(config.operation, top_drive_speed_hz=omega / (2 * np.pi),
                                    hook_load_n=hook)
    return dataclasses.replace(config, operation=operation)


def test_a_small_perturbation_grows_in_the_simulation_at_the_linear_rate():
    """
    The bit-speed oscillation grows at the predicted rate and frequency.

    The non-linear simulation (Newmark, exact bit solve) from steady drilling plus a
    1 mrad/s kick.
    """
    config, system = _system('reduced_basis.torsional_modes=2', 'reduced_basis.axial_modes=1',
                             'integration.time_step_s=0.01')
    law = BitRockLaw.from_config(config.bit_rock)
    omega, wob = 8.0, 150e3
    steady = SteadyDrilling.of(law, omega, wob)
    predicted = AxialTorsionalLinearisation(system).at(steady)
    assert predicted.growth_rate_per_s > 0.2
    hook = hook_load_for(system, wob)
    torsion = system.blocks['torsional']
    with threadpool_limits(limits=1, user_api='blas'):
        simulator = Simulator(_point_config(config, omega, hook), system=system)
        q, q_rate = steady_coordinates(system, steady, hook, simulator.state.q,
                                       simulator.state.q_rate)
        q_rate[:, torsion.columns.start] = 1e-3 / torsion.shapes[system.bit_node][0]
        simulator.reset(q, q_rate)
        deviation = []
        for _ in range(int(round(12.0 / simulator.dt))):
            simulator.step()
            deviation.append(simulator.last.bit_speed_rad_per_s[0] - omega)
    deviation = np.array(deviation)
    time = simulator.dt * np.arange(1, deviation.size + 1)
    peaks = np.flatnonzero((deviation[1:-1] > deviation[:-2]) & (deviation[1:-1] >= deviation[2:])
                           & (deviation[1:-1] > 0)) + 1
    peaks = peaks[time[peaks] > 2.0]                  # after the second mode has died out
    assert deviation.max() < 0.1 * omega              # still small: the linear regime
    growth = np.polyfit(time[peaks], np.log(deviation[peaks]), 1)[0]
    frequency = (peaks.size - 1) / (time[peaks[-1]] - time[peaks[0]])
    assert_allclose(growth, predicted.growth_rate_per_s, rtol=0.05)
    assert_allclose(frequency, predicted.frequency_hz, rtol=0.03)
