"""
Rayleigh's beta damping read as internal (rotating) damping.

The growth rates of the full finite-element model against the first-order closed form of every
mode pair (Jeffcott): sigma = -alpha/2 - beta omega_k^2/2 +/- beta Omega omega_k/2 (forward +,
backward -), and all negative for the paper's fixed-frame damping.
"""
from __future__ import annotations

import numpy as np
import pytest
from conftest import config_with, default_raw

from drill_twin.fem.whirl_stability import whirl_growth_rates
from drill_twin.modal.reduced_basis import modal_analysis


@pytest.fixture(scope='module')
def coarse():
    """
    Return the paper's prestressed string on 8 + 4 elements, without the fluid.

    The closed form leaves out the fluid's Coriolis and drag terms.
    """
    sections = [dict(s, elements=n) for s, n in zip(default_raw()['sections'], (8, 4))]
    config = config_with({'sections': sections, 'reduced_basis': {'lateral_modes': 44},
                          'physics': dict(default_raw()['physics'], fluid=False)})
    model, modes, _ = modal_analysis(config)
    lateral = (modes.kind == 'lateral') & ~modes.rigid
    omega = np.unique(np.round(2 * np.pi * modes.frequency_hz[lateral], 9))
    return config, model, omega


@pytest.mark.parametrize('spin', [5.2, 20.0])
def test_rotating_damping_growth_rates_follow_the_jeffcott_formula(coarse, spin):
    config, model, omega = coarse
    alpha = config.damping.mass_coefficient_per_s
    beta = config.damping.stiffness_coefficient_s
    growth, frequency, forward = whirl_growth_rates(model, spin)
    low = omega[omega < 12.0]                   # light damping: first order holds
    checked = 0
    for omega_k in low:
        pair = np.abs(frequency - omega_k) < 1e-3 * omega_k + 1e-4
        assert pair.sum() == 2
        common = -alpha / 2 - beta * omega_k ** 2 / 2
        split = beta * spin * omega_k / 2
        backward_rate, forward_rate = growth[pair & ~forward], growth[pair & forward]
        np.testing.assert_allclose([backward_rate[0], forward_rate[0]],
                                   [common - split, common + split], rtol=0.02, atol=2e-6)
        checked += 1
    assert checked >= 10
    unstable = low[low + alpha / (beta * low) < spin]  # forward whirl grows for these modes
    assert (growth.max() > 0) == (unstable.size > 0)
    assert (spin == 20.0) == (unstable.size > 0)       # Omega* = 2 sqrt(alpha/beta) = 11.5


def test_the_papers_fixed_frame_damping_is_stable(coarse):
    _, model, _ = coarse
    growth, _, _ = whirl_growth_rates(model, 20.0, rotating_damping=False)
    assert growth.max() < 0
