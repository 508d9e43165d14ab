"""
Rayleigh's beta damping acting on the strain rates of the spinning string, in the time loop.

``lateral_readings.stiffness_damping: rotating_frame`` adds the circulatory force beta Omega
K_t J u (model/rotating_damping.py). Checked against physics, not against itself: the
linearised string spinning at a constant speed above Omega* = 2 sqrt(alpha / beta) whirls
forward and its lateral energy grows at twice the largest growth rate of the eigenvalue
analysis (fem/whirl_stability.py, itself checked against Jeffcott's formula), at that mode's
whirl frequency; the lateral energy balance closes with that term as the only source; with
the paper's fixed-frame reading the same string decays.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import config_with, default_raw, physics_off
from threadpoolctl import threadpool_limits

from drill_twin.analysis.power_balance import LateralEnergyBalance
from drill_twin.model.rotating_damping import (RotatingDampingOperators,
                                               rotating_damping_force)
from drill_twin.integrator.simulator import Simulator
from drill_twin.fem.whirl_stability import quarter_turn, whirl_growth_rates

SPIN_RAD_PER_S = 20.0
ALPHA_PER_S, BETA_S = 0.01, 0.003                 # Omega* = 2 sqrt(alpha / beta) = 3.7 rad/s


def _config(reading: str):
    """Return the paper's prestressed string on 8 + 4 elements, linear, spun at 20 rad/s."""
    sections = [dict(s, elements=n) for s, n in zip(default_raw()['sections'], (8, 4))]
    physics = dict(physics_off(), gravity=True, prestress=True, stabilizers=True)
    return config_with({
        'sections': sections, 'reduced_basis': {'lateral_modes': 44}, 'physics': physics,
        'damping': {'mass_coefficient_per_s': ALPHA_PER_S, 'stiffness_coefficient_s': BETA_S},
        'operation': {'top_drive_speed_hz': SPIN_RAD_PER_S / (2 * math.pi)},
        'initial_conditions': {'lateral_deflection_m': 0.0},
        'lateral_readings': {'stiffness_damping': reading}})


def _run(reading: str, seconds: float):
    """
    Return (simulator, balance, times, lateral energy, v and w at a BHA node, eigenvalues).

    The string starts in the least stable whirl mode of the rotating reading's eigenvalue
    analysis (1 mm at its largest), projected on the reduced basis; the eigenvalues are
    (growth rate, frequency, forward) of whirl_growth_rates and the index of that mode.
    """
    simulator = Simulator(_config(reading))
    system = simulator.system
    growth, frequency, forward, shapes = whirl_growth_rates(
        simulator.system.model, SPIN_RAD_PER_S, shapes=True)
    least = int(np.argmax(growth))
    shape = shapes[:, least] * (1e-3 / np.max(np.abs(shapes[:, least])))
    s = growth[least] + 1j * frequency[least]
    phi = np.zeros((system.n_dofs, system.size))
    for block in system.blocks.values():
        phi[block.rows, block.columns] = block.shapes
    lateral = np.zeros(system.size, dtype=bool)
    for name in ('bending_y', 'bending_z'):
        lateral[system.blocks[name].columns] = True

    def coordinates(u):
        return np.linalg.lstsq(phi[:, lateral], u[system.permutation], rcond=None)[0]

    q, q_rate = simulator.state.q.copy(), simulator.state.q_rate.copy()
    q[0, lateral] = coordinates(shape.real)
    q_rate[0, lateral] = coordinates((s * shape).real)
    simulator.reset(q, q_rate)
    balance = LateralEnergyBalance(simulator)
    node = int(np.argmin(np.abs(system.model.mesh.node_x_m - 1550.0)))
    v_row = system.blocks['bending_y'].shapes[node]
    w_row = system.blocks['bending_z'].shapes[node]
    times, energy, orbit = [], [], []
    with threadpool_limits(limits=1, user_api='blas'):
        for _ in range(int(round(seconds / simulator.dt))):
            simulator.step()
            balance.update()
            state = simulator.state
            times.append(state.time_s)
            energy.append(balance.energy_j()[0])
            orbit.append((state.q[0, system.blocks['bending_y'].columns] @ v_row,
                          state.q[0, system.blocks['bending_z'].columns] @ w_row))
    return (simulator, balance, np.array(times), np.array(energy), np.array(orbit),
            (growth, frequency, forward, least))


def test_at_uniform_spin_the_force_is_beta_omega_k_j_u():
    """The kernel's force at a uniform spin against the dense beta Omega K_t J u (permuted)."""
    simulator = Simulator(_config('rotating_frame'))
    system, model = simulator.system, simulator.system.model
    operators = RotatingDampingOperators.of(system)
    assert operators.on
    generator = np.random.default_rng(7)
    u = generator.standard_normal((3, system.n_dofs))
    spin = np.full((3, system.n_nodes), 12.5)
    force = rotating_damping_force(system, u, spin, operators)
    dense = BETA_S * 12.5 * (model.total_stiffness.toarray() @ quarter_turn(model.n_dofs))
    p = system.permutation
    expected = u @ dense[np.ix_(p, p)].T
    lateral = slice(2 * system.n_nodes, 6 * system.n_nodes)
    expected[:, :lateral.start] = 0.0                 # the circulatory force is lateral only
    np.testing.assert_allclose(force, expected, rtol=1e-12,
                               atol=1e-12 * np.max(np.abs(expected)))
    assert not RotatingDampingOperators.of(Simulator(_config('fixed_frame')).system).on


def test_above_the_threshold_the_string_whirls_forward_at_the_eigenvalues_rate():
    """
    Spin 20 rad/s, alpha 0.01 /s, beta 0.003 s: the least stable lateral eigenvalue grows.

    Started in that whirl mode, the time loop's lateral energy grows at 2 sigma_max over
    5-20 s (within 0.5 %), the BHA whirls forward at that eigenvalue's frequency (0.5 %),
    and the energy balance closes with the rotating term as the source.
    """
    _, balance, times, energy, orbit, eigen = _run('rotating_frame', 20.0)
    growth, frequency, forward, least = eigen
    assert forward[least] and growth[least] > 0.05
    late = times >= 5.0
    slope = np.polyfit(times[late], np.log(energy[late]), 1)[0]
    assert slope == pytest.approx(2.0 * growth[least], rel=0.005)
    angle = np.unwrap(np.arctan2(orbit[late, 1], orbit[late, 0]))
    whirl = np.polyfit(times[late], angle, 1)[0]
    assert whirl == pytest.approx(frequency[least], rel=0.005)      # > 0: forward
    work = balance.work_j
    assert work['rotating_damping'][0] > 0 > work['damping'][0]
    gained = energy[-1] - balance.energy_at_start_j[0]
    assert abs(balance.closure_j()[0]) < 1e-4 * work['rotating_damping'][0]
    assert work['rotating_damping'][0] > gained


def test_the_papers_fixed_frame_damping_lets_the_same_whirl_decay():
    _, balance, times, energy, _, _ = _run('fixed_frame', 20.0)
    assert energy[-1] < 0.5 * energy[0]
    assert not np.any(balance.work_j['rotating_damping'])
