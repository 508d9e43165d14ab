"""The paper's string, coarse, with an imbalance in the BHA: a configuration shared by tests."""
from __future__ import annotations

import numpy as np
from conftest import config_with, default_raw

PIPE, COLLAR = 8, 4                      # a coarse mesh: every lateral mode in the basis
POSITION_M, MASS_KG, ECCENTRICITY_M = 1500.0, 500.0, 0.01


def imbalanced_string(spin_rad_per_s=5.2, alpha=0.5, time_step_s=0.01, **physics):
    """
    Return the paper's string on a coarse mesh with an imbalance in the BHA.

    It spins freely at the bit (no bit-rock law, no wall); f_se and f_ke off (the closed form
    is linear) unless ``physics`` switches them on.
    """
    switches = dict(default_raw()['physics'], bit_rock=False, contact=False,
                    finite_strain=False, kinetic_coupling=False)
    switches.update(physics)
    sections = [dict(s, elements=n) for s, n in zip(default_raw()['sections'], (PIPE, COLLAR))]
    return config_with({
        'physics': switches, 'sections': sections,
        'reduced_basis': {'lateral_modes': 4 * (PIPE + COLLAR + 1) - 8},
        'operation': {'top_drive_speed_hz': spin_rad_per_s / (2 * np.pi)},
        'damping': {'mass_coefficient_per_s': alpha},
        'integration': {'time_step_s': time_step_s},
        'initial_conditions': {'lateral_deflection_m': 0.0},
        'excitation': {'imbalance': {'enabled': True, 'position_m': POSITION_M,
                                     'mass_kg': MASS_KG, 'eccentricity_m': ECCENTRICITY_M}}})
