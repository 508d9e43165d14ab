"""Readings of the paper selectable for its lateral response (docs/LATERAL.md)."""
from __future__ import annotations

import numpy as np
from conftest import config_with, default_raw

from drill_twin.model.forces import Kinematics
from drill_twin.model.kinetic_coupling import kinetic_coupling_energy, kinetic_coupling_force
from drill_twin.model.reduced_system import build_reduced_system
from drill_twin.modal.reduced_basis import modal_analysis


def _system(sign):
    sections = [dict(s, elements=n) for s, n in zip(default_raw()['sections'], (8, 4))]
    config = config_with({'sections': sections, 'reduced_basis': {'lateral_modes': 44},
                          'lateral_readings': {'kinetic_coupling': sign}})
    model, _, basis = modal_analysis(config)
    return build_reduced_system(model, basis)


def test_printed_kinetic_coupling_is_the_derived_one_with_the_opposite_sign(default_config):
    assert default_config.lateral_readings.kinetic_coupling == 'derived'
    derived, printed = _system('derived'), _system('printed')
    rng = np.random.default_rng(9)
    q, rate, acceleration = (rng.normal(size=(2, derived.size)) for _ in range(3))
    forces, energies = [], []
    for system in (derived, printed):
        fields = Kinematics.of(system, q, rate, acceleration, 5.2, 0.3)
        forces.append(kinetic_coupling_force(system, fields))
        energies.append(kinetic_coupling_energy(system, fields))
    assert np.abs(forces[0]).max() > 0 and np.abs(energies[0]).max() > 0
    np.testing.assert_allclose(forces[1], -forces[0], rtol=1e-12, atol=0)
    np.testing.assert_allclose(energies[1], -energies[0], rtol=1e-12, atol=0)


def _lateral_readings_module():
    """benchmarks/lateral_readings.py, which tabulates runs against the paper's figures."""
    import importlib.util
    from pathlib import Path
    path = Path(__file__).resolve().parents[2] / 'benchmarks' / 'lateral_readings.py'
    spec = importlib.util.spec_from_file_location('lateral_readings', path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _run(path, radial, t, impacts, lift_offs):
    n = t.size
    np.savez(path, time_s=t, x700m_radial_m=radial, impacts_so_far=impacts,
             lift_offs_so_far=lift_offs, max_contact_force_n=np.linspace(0.0, 2e3, n),
             bit_speed_rad_per_s=np.full(n, 5.0), torque_on_bit_nm=np.full(n, 7e3),
             top_torque_nm=np.full(n, 1.4e4))
    return path


def test_the_lateral_table_reads_known_signals(tmp_path):
    """
    The amplitude, spectrum and event counts of the lateral table on signals with known answers.

    A displacement 0.5 (1 + sin 2 pi 0.3 t) b_k whose envelope b_k is constant over each 5 s
    span of the window 200-250 s: its amplitude (the smallest of the spans' largest values) is
    min b_k. A sine of 0.3 Hz, 15 periods in the window, puts the centred energy in the
    0.1-0.5 Hz band. Events: counts before and inside the window.
    """
    readings = _lateral_readings_module()
    t = np.round(np.arange(0.0, 260.0 + 1e-9, 0.01), 10)
    envelope = np.full(t.size, 0.06)
    spans = [0.04, 0.03, 0.05, 0.025, 0.045, 0.035, 0.05, 0.04, 0.03, 0.055]
    for k, b in enumerate(spans):
        envelope[(t >= 200 + 5 * k - 1e-9) & (t < 205 + 5 * k - 1e-9)] = b
    wave = 0.5 * (1.0 + np.sin(2 * np.pi * 0.3 * t))
    impacts = (t >= 100).astype(int) + (t >= 210) + (t >= 220)
    lift_offs = (t >= 230).astype(int)
    row = readings.row(_run(tmp_path / 'a.npz', envelope * wave, t, impacts, lift_offs),
                       200.0, 250.0, 5.0)
    assert abs(row['amplitude_min_cm'] - 100 * min(spans)) < 1e-3 * 100 * min(spans)
    assert (row['impacts_window'], row['impacts_run']) == (2, 3)
    assert (row['lift_offs_window'], row['lift_offs_run']) == (1, 1)
    assert row['wall_force_max_kn'] == 2.0 and row['bit_speed_min'] == 5.0

    pure = 0.02 + 0.01 * np.sin(2 * np.pi * 0.3 * t)
    row = readings.row(_run(tmp_path / 'b.npz', pure, t, impacts, lift_offs), 200.0, 250.0)
    # 15 periods plus the window's closing sample: a leakage of about 2e-6.
    assert row['0.1-0.5Hz'] > 1 - 1e-4 and row['below_0.1Hz'] < 1e-4
    assert abs(row['radial_mean_cm'] - 2.0) < 1e-6 and abs(row['radial_max_cm'] - 3.0) < 1e-4
    assert abs(row['at_least_2cm'] - 0.5) < 0.01
