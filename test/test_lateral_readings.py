"""Readings of the paper selectable for its lateral response (issue 12, section 1)."""
from __future__ import annotations

import numpy as np
from conftest import config_with, default_raw

from drill_twin.dynamics.forces import Kinematics
from drill_twin.dynamics.kinetic_coupling import kinetic_coupling_energy, kinetic_coupling_force
from drill_twin.dynamics.reduced_system import build_reduced_system
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
