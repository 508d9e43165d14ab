"""
Eigenfrequencies in the analytic limits, at the default mesh density, and their convergence.

The default string has 56 elements over 1600 m. The uniform strings below keep that density
(56 equal elements of 28.6 m). On the default *graded* mesh (43.75 m pipe elements) the
5th fixed-free axial/torsional frequency is 0.56 % high (consistent mass, linear elements);
docs/VALIDATION.md, "Table 1", reports it.
"""
from __future__ import annotations

import numpy as np
import pytest
from analytic import (fixed_free_rod_hz, rod_with_tip_inertia_hz, tensioned_pinned_beam_hz,
                      timoshenko_cantilever_hz)
from conftest import config_with, default_raw, physics_off

from drill_twin.fem.model import build_model
from drill_twin.modal.normal_modes import solve_normal_modes

LENGTH = 1600.0
PIPE = default_raw()['sections'][0]
E, RHO, NU, KS = 210e9, 7850.0, 0.29, 6 / 7
G = E / (2 * (1 + NU))
AREA = np.pi / 4 * (0.127 ** 2 - 0.095 ** 2)
INERTIA = np.pi / 64 * (0.127 ** 4 - 0.095 ** 4)
TOLERANCE = 0.005


def _uniform_string(elements=56, length=LENGTH, section=PIPE, physics=None, boundary=None,
                    **changes):
    boundary = {'top_axial': 'fixed', 'top_torsion': 'driven', 'top_lateral': 'clamped',
                'bit_axial': 'free', 'bit_torsion': 'free', 'bit_lateral': 'clamped',
                **(boundary or {})}
    return config_with({'sections': [dict(section, length_m=length, elements=elements)],
                        'stabilizers': [], 'physics': physics or physics_off(),
                        'boundary': boundary, 'output': {'stations_m': []}, **changes})


def _frequencies(config, kind, count):
    modes = solve_normal_modes(build_model(config))
    return modes.frequency_hz[(modes.kind == kind) & ~modes.rigid][:count]


def _pairs(frequencies):
    """One frequency of each (v, w) pair of a symmetric string."""
    np.testing.assert_allclose(frequencies[0::2], frequencies[1::2], rtol=1e-6)
    return frequencies[0::2]


@pytest.mark.parametrize('kind, wave_speed', [('axial', np.sqrt(E / RHO)),
                                              ('torsional', np.sqrt(KS * G / RHO))])
def test_fixed_free_rod(kind, wave_speed):
    """Axial speed sqrt(E/rho); torsion with k_s G I_p (MODEL.md point 1): sqrt(k_s G/rho)."""
    computed = _frequencies(_uniform_string(), kind, 5)
    expected = fixed_free_rod_hz(5, LENGTH, wave_speed)
    np.testing.assert_allclose(computed, expected, rtol=TOLERANCE)


@pytest.mark.parametrize('ratio', [1.0, 0.2])
def test_rod_with_rigid_tip_inertia(ratio):
    """Solve beta tan beta = mu with mu = (rod inertia) / (tip inertia), axial and torsional."""
    mass = RHO * AREA * LENGTH / ratio
    polar = RHO * 2 * INERTIA * LENGTH / ratio
    config = _uniform_string(bit={'mass_kg': mass, 'polar_inertia_kg_m2': polar})
    for kind, speed in (('axial', np.sqrt(E / RHO)), ('torsional', np.sqrt(KS * G / RHO))):
        computed = _frequencies(config, kind, 5)
        expected = rod_with_tip_inertia_hz(5, LENGTH, speed, ratio)
        np.testing.assert_allclose(computed, expected, rtol=TOLERANCE)


def test_tensioned_pinned_pinned_beam():
    """Uniform tension T from a pulling load at the bit (gravity and fluid off)."""
    tension = 1.0e5
    physics = dict(physics_off(), prestress=True)
    config = _uniform_string(physics=physics,
                             boundary={'top_lateral': 'pinned', 'bit_lateral': 'pinned'},
                             bit_rock={'static_weight_on_bit_n': tension})
    computed = _pairs(_frequencies(config, 'lateral', 10))
    expected = tensioned_pinned_beam_hz(5, LENGTH, E * INERTIA, tension, RHO * AREA)
    np.testing.assert_allclose(computed, expected, rtol=TOLERANCE)


def test_slack_pinned_pinned_beam_is_euler_bernoulli():
    """No tension: the bending frequencies of a slender pinned beam."""
    config = _uniform_string(length=200.0, boundary={'top_lateral': 'pinned',
                                                     'bit_lateral': 'pinned'})
    computed = _pairs(_frequencies(config, 'lateral', 10))
    expected = tensioned_pinned_beam_hz(5, 200.0, E * INERTIA, 0.0, RHO * AREA)
    np.testing.assert_allclose(computed, expected, rtol=TOLERANCE)


def test_timoshenko_cantilever():
    """A short, thick collar (L/r = 59) where shear and rotary inertia matter."""
    collar = default_raw()['sections'][1]
    length = 4.0
    config = _uniform_string(elements=collar['elements'], length=length, section=collar,
                             boundary={'bit_lateral': 'free'})
    area = np.pi / 4 * (0.2286 ** 2 - 0.0762 ** 2)
    inertia = np.pi / 64 * (0.2286 ** 4 - 0.0762 ** 4)
    computed = _pairs(_frequencies(config, 'lateral', 10))
    expected = timoshenko_cantilever_hz(5, length, E, G, KS, RHO, area, inertia)
    np.testing.assert_allclose(computed, expected, rtol=TOLERANCE)
    euler = (np.array([1.8751, 4.6941, 7.8548, 10.9955, 14.1372]) ** 2
             * np.sqrt(E * inertia / (RHO * area)) / length ** 2 / (2 * np.pi))
    # Shear and rotary inertia lower modes 3-5 by 3-9 %: far beyond the tolerance.
    assert np.all(expected[2:] < 0.97 * euler[2:])


def test_axial_frequencies_converge_at_second_order():
    errors = []
    expected = fixed_free_rod_hz(5, LENGTH, np.sqrt(E / RHO))
    for elements in (28, 56, 112):
        computed = _frequencies(_uniform_string(elements=elements), 'axial', 5)
        errors.append(np.abs(computed / expected - 1))
    ratios = np.array(errors[0]) / np.array(errors[1]), np.array(errors[1]) / np.array(errors[2])
    for ratio in ratios:
        np.testing.assert_allclose(ratio, 4.0, rtol=0.05)


def test_timoshenko_cantilever_converges_under_refinement():
    collar = default_raw()['sections'][1]
    area = np.pi / 4 * (0.2286 ** 2 - 0.0762 ** 2)
    inertia = np.pi / 64 * (0.2286 ** 4 - 0.0762 ** 4)
    expected = timoshenko_cantilever_hz(5, 4.0, E, G, KS, RHO, area, inertia)
    errors = []
    for elements in (6, 12, 24):
        config = _uniform_string(elements=elements, length=4.0, section=collar,
                                 boundary={'bit_lateral': 'free'})
        errors.append(np.abs(_pairs(_frequencies(config, 'lateral', 10)) / expected - 1).max())
    assert errors[0] > errors[1] > errors[2]
    assert errors[1] / errors[2] > 3.0
