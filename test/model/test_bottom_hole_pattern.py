"""
The lobed hole bottom (``excitation.bottom_hole_pattern``).

Checked against the closed form of the linearised string (the weight on bit's steady
harmonic answer to lobes of small height), the kinematics of the hole (what the reported ROP
integrates to) and the bounce of high lobes (lift-off, landing, the hole only deepens);
docs/LATERAL.md, "A lobed hole bottom: bit bounce", gives the figures.
"""
from __future__ import annotations

import numpy as np
import pytest
from conftest import config_with, default_raw

from drill_twin.config import ConfigError
from drill_twin.integrator.simulator import Simulator
from drill_twin.rig.rig import Rig

PIPE, COLLAR = 8, 4                      # a coarse mesh: fast, and the closed form is exact in
LOBES = 3                                # the reduced basis whatever the mesh


def _config(amplitude_m, spin_rad_per_s=3.0, alpha=0.5, **changes):
    """
    Return the paper's string on a coarse mesh with lobes under the bit.

    Steady drilling at 100 kN (the stick-slip map: steady below about 4 rad/s), from the
    steady twist; f_se, f_ke and the wall off, so that the bit-rock law is the only
    non-linearity; Rayleigh alpha 0.5 /s so that the start's transient dies out.
    """
    switches = dict(default_raw()['physics'], contact=False, finite_strain=False,
                    kinetic_coupling=False)
    sections = [dict(s, elements=n) for s, n in zip(default_raw()['sections'], (PIPE, COLLAR))]
    raw = {
        'physics': switches, 'sections': sections,
        'reduced_basis': {'lateral_modes': 8},
        'operation': {'top_drive_speed_hz': spin_rad_per_s / (2 * np.pi)},
        'damping': {'mass_coefficient_per_s': alpha},
        'initial_conditions': {'lateral_deflection_m': 0.0, 'steady_twist': True},
        'excitation': {'bottom_hole_pattern': {'enabled': True, 'lobes': LOBES,
                                               'amplitude_m': amplitude_m}}}
    raw.update(changes)
    return config_with(raw)


def test_the_pattern_is_off_by_default_and_validated(default_config):
    pattern = default_config.excitation.bottom_hole_pattern
    assert not pattern.enabled and pattern.height_m == 0.0
    with pytest.raises(ConfigError, match='excitation.bottom_hole_pattern.lobes'):
        config_with({'excitation': {'bottom_hole_pattern': {'lobes': 0}}})
    with pytest.raises(ConfigError, match='excitation.bottom_hole_pattern.amplitude_m'):
        config_with({'excitation': {'bottom_hole_pattern': {'amplitude_m': 0.5}}})
    with pytest.raises(ConfigError, match='needs a compliant rock'):
        config_with({'bit_rock': {'contact_stiffness_n_per_m': None},
                     'excitation': {'bottom_hole_pattern': {'enabled': True}}})


def _closed_form(simulator, amplitude_m):
    """
    Return the complex amplitude C of the weight on bit's answer, WOB = f0 + Re(C e^(i n phi)).

    Linearised about the steady state, the reduced model is M q'' + C q' + K q = B dF with
    dF = J (B^T q' - (ds/dt, 0)), J the law's Jacobian d(f, t)/d(ROP, omega) there and
    ds/dt = Re(A n Omega e^(i n phi)), phi = Omega t + const: at nu = n Omega,
    (K - nu^2 M + i nu (C - B J B^T)) Q = -B J (A n Omega, 0), dF = J (i nu B^T Q - (A n
    Omega, 0)).
    """
    integrator = simulator.integrator
    state = simulator.state
    omega = state.top_speed_rad_per_s
    rop = state.q_rate @ integrator.bit_rows[0]
    bit_speed = omega + state.q_rate @ integrator.bit_rows[1]
    _, _, _, jacobian = integrator.forces.law.forces_and_jacobian(rop, bit_speed)
    jacobian = jacobian[0]
    nu = LOBES * omega
    b = integrator.bit_rows_t                                   # (n, 2)
    dynamic = (integrator.stiffness - nu ** 2 * integrator.mass
               + 1j * nu * (integrator.damping - b @ jacobian @ b.T))
    surface_rate = np.array([amplitude_m * LOBES * omega, 0.0])
    modal = np.linalg.solve(dynamic, -b @ (jacobian @ surface_rate))
    return (jacobian @ (1j * nu * (b.T @ modal) - surface_rate))[0]


def test_the_weight_on_bit_answers_small_lobes_as_the_linearised_string():
    """
    Lobes of 20 um at 3 rad/s: the WOB oscillates at 3 Omega as the closed form says.

    Its complex amplitude (fitted on cos and sin of n phi_bit over the last 5 s of 25 s)
    within 2 % of the closed form's (magnitude and phase); a lobed surface that moved the
    bit at ds/dt of the wrong sign, size or phase, or a law not read relative to the surface,
    fails it.
    """
    amplitude = 2e-5
    simulator = Simulator(_config(amplitude))
    expected = _closed_form(simulator, amplitude)
    steps = int(round(25.0 / simulator.dt))
    window = int(round(5.0 / simulator.dt))
    angle, weight = [], []
    for k in range(steps):
        simulator.step()
        if k >= steps - window:
            seen = simulator.observe()
            angle.append(seen.angle_rad[0])
            weight.append(seen.weight_on_bit_n[0])
    phase = LOBES * np.array(angle)
    design = np.column_stack([np.ones_like(phase), np.cos(phase), -np.sin(phase)])
    coefficients = np.linalg.lstsq(design, np.array(weight), rcond=None)[0]
    fitted = coefficients[1] + 1j * coefficients[2]
    assert abs(expected) > 10.0                  # tens of newtons: the BHA rides the lobes
    assert abs(fitted - expected) < 0.02 * abs(expected), (fitted, expected)


def test_the_hole_deepens_by_the_reported_rop_while_the_bit_follows_the_lobes():
    """
    Over 10 s on 0.2 mm lobes the integral of the reported ROP is the hole's deepening.

    The reported ROP is the rate relative to the moving surface (what the hole's mean bottom
    does), while the bit's own axial velocity swings with the lobes by about A n Omega. (The
    first second is left out: the bit starts at the mean ROP, not on the lobes, and its first
    step presses the rock deeper by up to 2 A n Omega a2 / k.)
    """
    amplitude = 2e-4
    simulator = Simulator(_config(amplitude))
    for _ in range(int(round(1.0 / simulator.dt))):
        simulator.step()
    start = simulator.hole_depth_m[0]
    rops, velocities = [], []
    for _ in range(int(round(10.0 / simulator.dt))):
        simulator.step()
        seen = simulator.observe()
        rops.append(seen.rop_m_per_s[0])
        velocities.append(seen.bit_axial_velocity_m_per_s[0])
    rops, velocities = np.array(rops), np.array(velocities)
    deepened = simulator.hole_depth_m[0] - start
    assert deepened > 0.01
    assert np.sum(rops) * simulator.dt == pytest.approx(deepened, rel=2e-3)
    swing = 0.5 * np.ptp(velocities - rops)
    assert swing == pytest.approx(amplitude * LOBES * 3.0, rel=0.05)


def test_high_lobes_bounce_the_bit_and_every_bounce_lands():
    """
    5 mm lobes at the paper's 5.2 rad/s and 100 kN lift the bit off, and it lands again.

    The surface accelerates at A (n Omega)^2 = 1.2 m/s^2: more than the weight on bit over the
    string's apparent mass; the rock throws the bit up on the lobes (3 mm: WOB down to 7 kN,
    no lift-off). The hole only deepens.
    """
    simulator = Simulator(_config(5e-3, spin_rad_per_s=5.2))
    depth, flags = [], []
    for _ in range(int(round(10.0 / simulator.dt))):
        result = simulator.step()
        depth.append(simulator.hole_depth_m[0])
        # The step kernel's on-bottom flag (what the landing count takes) is the state's test.
        assert result.on_bottom[0] == simulator.on_bottom()[0]
        flags.append(result.on_bottom[0])
    assert simulator.lift_off_count[0] >= 5
    assert simulator.landing_count[0] >= simulator.lift_off_count[0] - 1
    assert simulator.landing_count[0] == np.count_nonzero(np.diff(np.array(flags, int)) == 1)
    assert np.all(np.diff(depth) >= 0.0)


def test_the_step_reports_the_bit_on_bottom_as_the_state_does_on_a_flat_bottom():
    """A bit picked up off a flat bottom and set down again: the flag follows, it lands."""
    config = _config(5e-3, excitation={'bottom_hole_pattern': {'enabled': False}})
    simulator = Simulator(config)
    rig = Rig(simulator)
    hook = rig.hook_load_command_n
    flags = []
    for load_change_n, seconds in ((0.0, 0.5), (150e3, 2.0), (-100e3, 4.0)):
        rig.set_hook_load(hook + load_change_n)
        for _ in range(int(round(seconds / simulator.dt))):
            result = rig.step()
            assert result.on_bottom[0] == simulator.on_bottom()[0]
            flags.append(result.on_bottom[0])
    flags = np.array(flags)
    assert flags[0] and not flags.all() and flags[-1]
    landings = np.count_nonzero(np.diff(flags.astype(int)) == 1)
    assert landings >= 1 and simulator.landing_count[0] == landings
