"""
Pre-flight check (drill_twin.analysis.preflight).

The default configuration passes with the operating point the bit-rock law and the string's
weight give; laws, loads and models that cannot be integrated are refused with one line.
"""
from __future__ import annotations

import math
import subprocess
import sys

import pytest

from drill_twin.config import load_config
from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.analysis.preflight import (ROP_MAX_M_PER_S, PreflightError, build_model,
                                           check_operating_point, check_short_run)
from drill_twin.model.reduced_system import build_reduced_system


def test_default_operating_point_is_the_law_and_the_weight_in_air(default_config,
                                                                  default_analysis):
    model = default_analysis[0]
    point = check_operating_point(default_config, model)
    # The string's weight as the model counts it (MODEL.md: weight in air, no net buoyancy):
    # sum of rho A L g over the sections.
    weight = sum(s.density_kg_per_m3 * math.pi / 4 * (s.outer_diameter_m ** 2
                                                      - s.inner_diameter_m ** 2)
                 * s.length_m * default_config.gravity_m_per_s2 for s in default_config.sections)
    assert point.string_weight_n == pytest.approx(weight, rel=1e-3)
    assert point.weight_on_bit_n == default_config.bit_rock.static_weight_on_bit_n
    # Eq. 24, regularised (Z = omega / sqrt(omega^2 + e^2)), written out by hand.
    b = default_config.bit_rock
    omega = 2 * math.pi * default_config.operation.top_drive_speed_hz
    z = omega / math.hypot(omega, b.regularization_rad_per_s)
    rop = z * z * (-b.a1_m_per_s - b.a2_m_per_n_s * point.weight_on_bit_n) \
        + b.a3_m_per_rad * omega * z
    assert point.rop_m_per_s == pytest.approx(rop, rel=1e-12)
    assert 1e-3 < point.rop_m_per_s < 3e-3                   # the paper's 1-3 mm/s
    s = omega ** 2 + b.regularization_rad_per_s ** 2
    torque = -b.a4_n_rad * rop * omega / s - b.a5_n_m * omega / math.sqrt(s)
    assert point.torque_on_bit_nm == pytest.approx(torque, rel=1e-12)
    assert abs(point.torque_on_bit_nm) < 0.05 * point.torque_capacity_nm


def test_default_configuration_passes_the_short_run(default_config, default_analysis):
    model, _, basis = default_analysis
    check_short_run(default_config, build_reduced_system(model, basis))


@pytest.mark.parametrize('override, words', [
    ('bit_rock.a1_m_per_s=10', 'steady ROP of -8.71 m/s'),           # the rock lifts the bit
    ('bit_rock.a2_m_per_n_s=1.0', 'steady ROP of 8.72e+04 m/s'),     # 87 km/s
    ('bit_rock.a4_n_rad=1e12', 'more than the string carries'),      # TOB -4.4e8 N m
])
def test_implausible_laws_are_refused(default_analysis, override, words):
    config = load_config(None, [override])
    with pytest.raises(PreflightError) as info:
        check_operating_point(config, default_analysis[0])
    assert info.value.key == 'bit_rock'
    assert words in info.value.message and '\n' not in str(info.value)


def test_the_bound_on_the_rop_is_the_stated_one(default_analysis):
    """a2 scaled so that the steady ROP is just above and just below ROP_MAX_M_PER_S."""
    config = load_config()
    law = BitRockLaw.from_config(config.bit_rock)
    omega, wob = config.operation.top_drive_speed_rad_per_s, -1e5
    z2 = omega ** 2 / (omega ** 2 + law.e ** 2)
    # ROP = z^2 (-a1 - a2 wob) + a3 omega z = bound  ->  a2
    a2 = ((ROP_MAX_M_PER_S - law.a3 * omega * math.sqrt(z2)) / z2 + law.a1) / -wob
    model = default_analysis[0]
    check_operating_point(load_config(None, [f'bit_rock.a2_m_per_n_s={a2 * 0.999}']), model)
    with pytest.raises(PreflightError, match='more than 0.1 m/s'):
        check_operating_point(load_config(None, [f'bit_rock.a2_m_per_n_s={a2 * 1.001}']), model)


def test_a_hook_load_above_the_weight_is_refused(default_analysis):
    model = default_analysis[0]
    weight = model.prestress.hook_load_n + 100e3              # H_S - f_c
    with pytest.raises(PreflightError) as info:
        check_operating_point(load_config(None, [f'operation.hook_load_n={weight + 1.0}']),
                              model)
    assert info.value.key == 'operation.hook_load_n'
    assert 'lifts the whole string' in info.value.message
    # 20 kN below the prestressed hook load: more weight on bit, drills faster.
    point = check_operating_point(load_config(
        None, [f'operation.hook_load_n={model.prestress.hook_load_n - 20e3}']), model)
    assert point.weight_on_bit_n == pytest.approx(-120e3)


def test_a_model_that_fails_at_once_is_refused_by_the_short_run():
    """
    A Newton solve allowed one iteration at an unreachable tolerance.

    The operating point is the paper's (it passes), but the first step fails even on sub-steps
    down to dt/16. (a4 = 7e8 N rad, whose bit equation had no solution at the first step,
    integrates since the bit's equation is solved as a monotone graph.)
    """
    config = load_config(None, ['integration.max_iterations=1', 'integration.tolerance=1e-14'])
    model, _, system = build_model(config)
    check_operating_point(config, model)
    with pytest.raises(PreflightError, match=r'cannot be integrated: .* at t = 0\.005 s'):
        check_short_run(config, system)


def test_a_model_that_cannot_be_built_is_one_line():
    with pytest.raises(PreflightError) as info:
        build_model(load_config(None, ['reduced_basis.lateral_modes=100000']))
    assert str(info.value) == ('the model cannot be built from it: reduced_basis.lateral_modes: '
                               'asked for 100000, the mesh has only 220 lateral modes')


def test_the_check_imports_no_ros():
    code = ('import sys, drill_twin.analysis.preflight; '
            'sys.exit(1 if "rclpy" in sys.modules else 0)')
    assert subprocess.run([sys.executable, '-c', code]).returncode == 0
