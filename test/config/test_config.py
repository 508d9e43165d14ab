"""Configuration: defaults, partial overrides, --set, and one-line errors for bad input."""
from __future__ import annotations

import math
import pickle
import subprocess
import sys

import pytest
from conftest import REPO, config_with, default_raw

from drill_twin.config import ConfigError, load_config
from drill_twin.config.checks import ConfigValueError
from drill_twin.config.loader import config_to_dict


def test_defaults_hold_every_value_of_appendix_c(default_config):
    """Appendix C of the paper, transcribed here independently of config/ritto2009.yaml."""
    c = default_config
    pipe, collar = c.sections
    assert c.operation.top_drive_speed_hz == 0.83
    assert (pipe.length_m, collar.length_m) == (1400.0, 200.0)
    assert (pipe.outer_diameter_m, pipe.inner_diameter_m) == (0.127, 0.095)
    assert (collar.outer_diameter_m, collar.inner_diameter_m) == (0.2286, 0.0762)
    assert c.borehole.diameter_m == 0.3
    assert c.stabilizers[0].position_m == 1400.0
    assert c.stabilizers[0].stiffness_n_per_m == 17.5e6
    for section in (pipe, collar):
        assert section.young_modulus_pa == 210e9
        assert section.density_kg_per_m3 == 7850.0
        assert section.poisson_ratio == 0.29
        assert section.shear_correction_factor == pytest.approx(6 / 7, rel=1e-15)
    assert c.borehole.contact_stiffness_n_per_m == 1e8
    assert c.borehole.friction_coefficient == 0.0005
    assert c.fluid.inlet_speed_m_per_s == 1.5
    assert c.fluid.density_kg_per_m3 == 1200.0
    assert c.fluid.drag_coefficient == 0.0125
    assert c.fluid.viscous_damping_n_s_per_m2 == 0.0
    assert c.gravity_m_per_s2 == 9.81
    b = c.bit_rock
    assert (b.a1_m_per_s, b.a2_m_per_n_s, b.a3_m_per_rad) == (3.429e-3, 5.672e-8, 1.374e-4)
    assert (b.a4_n_rad, b.a5_n_m, b.regularization_rad_per_s) == (9.537e6, 1.475e3, 2.0)
    assert b.static_weight_on_bit_n == -100e3
    assert (c.damping.mass_coefficient_per_s, c.damping.stiffness_coefficient_s) == (0.01, 3e-4)
    assert (pipe.elements, collar.elements) == (32, 24)
    basis = c.reduced_basis
    assert (basis.lateral_modes, basis.torsional_modes, basis.axial_modes) == (158, 4, 3)
    assert math.isclose(c.operation.top_drive_speed_rad_per_s, 2 * math.pi * 0.83)


def test_configuration_is_frozen(default_config):
    with pytest.raises(Exception):
        default_config.sections[0].length_m = 3.0


def test_partial_file_overrides_only_its_keys(tmp_path, default_config):
    path = tmp_path / 'mine.yaml'
    path.write_text(
        'fluid:\n  density_kg_per_m3: 1500\ndamping:\n  mass_coefficient_per_s: 2e-2\n')
    config = load_config(path)
    assert config.fluid.density_kg_per_m3 == 1500.0
    assert config.damping.mass_coefficient_per_s == 0.02
    assert config.fluid.inlet_speed_m_per_s == default_config.fluid.inlet_speed_m_per_s
    assert config.sections == default_config.sections


def test_a_file_can_describe_another_string(tmp_path):
    path = tmp_path / 'three.yaml'
    section = ('  - {{name: {0}, kind: {1}, length_m: {2}, outer_diameter_m: {3}, '
               'inner_diameter_m: {4}, elements: {5}, young_modulus_pa: 2.1e11, '
               'density_kg_per_m3: 7850, poisson_ratio: 0.3, shear_correction_factor: 0.857}}\n')
    path.write_text(
        'sections:\n'
        + section.format('dp', 'drill_pipe', 2000, 0.127, 0.1086, 40)
        + section.format('hwdp', 'heavy_weight_pipe', 150, 0.127, 0.0762, 10)
        + section.format('dc', 'drill_collar', 120, 0.2032, 0.0714, 12)
        + 'stabilizers:\n  - {name: s1, position_m: 2200, stiffness_n_per_m: 1e7}\n'
        + '  - {name: near_bit, position_m: 2268, stiffness_n_per_m: 2e7}\n')
    config = load_config(path)
    assert [s.kind for s in config.sections] == ['drill_pipe', 'heavy_weight_pipe', 'drill_collar']
    assert config.length_m == 2270.0
    assert len(config.stabilizers) == 2


def test_set_overrides_by_name_and_index():
    config = load_config(None, ['sections.drill_pipe.elements=40', 'output.stations_m.0=650',
                                'physics.fluid=false', 'fluid.coriolis=paper'])
    assert config.sections[0].elements == 40
    assert config.output.stations_m[0] == 650.0
    assert config.physics.fluid is False
    assert config.fluid.coriolis == 'paper'


def test_round_trip_through_a_plain_mapping(default_config):
    from drill_twin.config import build_config
    assert build_config(config_to_dict(default_config)) == default_config


@pytest.mark.parametrize('changes, key, words', [
    ({'sections': [dict(default_raw()['sections'][0], inner_diameter_m=0.13)]},
     'sections.drill_pipe.inner_diameter_m', 'smaller than outer_diameter_m'),
    ({'sections': [dict(default_raw()['sections'][0], outer_diameter_m=0.31)]},
     'sections.drill_pipe.outer_diameter_m', 'does not fit in the borehole'),
    ({'sections': [dict(default_raw()['sections'][0], length_m=-10.0)]},
     'sections.drill_pipe.length_m', 'positive'),
    ({'sections': [dict(default_raw()['sections'][0], elements=0)]},
     'sections.drill_pipe.elements', 'at least 1'),
    ({'fluid': {'density_kg_per_m3': 'heavy'}}, 'fluid.density_kg_per_m3', 'expected a number'),
    ({'fluid': {'colour': 'brown'}}, 'fluid.colour', 'unknown key'),
    ({'borehole': {'diameter_m': 0.2}}, 'sections.drill_collar.outer_diameter_m', 'borehole'),
    ({'stabilizers': [{'name': 's', 'position_m': 2000.0, 'stiffness_n_per_m': 1.0}]},
     'stabilizers.s.position_m', 'below the bit'),
    ({'physics': {'fluid': 'maybe'}}, 'physics.fluid', 'true or false'),
    ({'boundary': {'bit_lateral': 'glued'}}, 'boundary.bit_lateral', 'must be one of'),
    ({'bit_rock': {'static_weight_on_bit_n': 5e4}}, 'bit_rock.static_weight_on_bit_n', '<= 0'),
    ({'integration': {'time_step_s': 0.0}}, 'integration.time_step_s', 'positive'),
    ({'sections': [dict(default_raw()['sections'][0], poisson_ratio=0.7)]},
     'sections.drill_pipe.poisson_ratio', '(-1, 0.5)'),
    # Plausibility: finite but beyond any drill string (and beyond floating point downstream).
    ({'gravity_m_per_s2': 1e308}, 'gravity_m_per_s2', 'at most 30 (no planet'),
    ({'sections': [dict(default_raw()['sections'][0], young_modulus_pa=1e308)]},
     'sections.drill_pipe.young_modulus_pa', 'at most 1.2e+12 (from polymers'),
    ({'sections': [dict(default_raw()['sections'][0], young_modulus_pa=2.1e5)]},
     'sections.drill_pipe.young_modulus_pa', 'at least 1e+09'),
    ({'sections': [dict(default_raw()['sections'][0], length_m=1e6)]},
     'sections.drill_pipe.length_m', 'no well is longer'),
    ({'sections': [dict(default_raw()['sections'][0], elements=5000)]},
     'sections.drill_pipe.elements', 'the modal analysis is dense'),
    ({'operation': {'hook_load_n': -1.0}}, 'operation.hook_load_n', 'a hook can only pull'),
    ({'operation': {'top_drive_speed_hz': -83.0}}, 'operation.top_drive_speed_hz',
     'at least -10'),
    ({'integration': {'time_step_s': 1.0}}, 'integration.time_step_s', 'at most 0.1'),
    # A step no run finishes with (the pre-flight alone would take 2.5e8 steps at 1e-9 s).
    ({'integration': {'time_step_s': 1e-9}}, 'integration.time_step_s',
     'at least 1e-05 (a step takes about 0.2 ms of computing'),
    ({'integration': {'time_step_s': 9.99e-6}}, 'integration.time_step_s', 'got 9.99e-06'),
    ({'initial_conditions': {'lateral_deflection_m': 0.5}},
     'initial_conditions.lateral_deflection_m', 'does not fit in the hole'),
])
def test_impossible_or_malformed_values_are_refused(changes, key, words):
    with pytest.raises(ConfigError) as info:
        config_with(changes)
    message = str(info.value)
    assert '\n' not in message
    assert f': {key}: ' in message
    assert words in message


def test_the_smallest_time_step_is_accepted():
    assert config_with({'integration': {'time_step_s': 1e-5}}).integration.time_step_s == 1e-5


@pytest.mark.parametrize('error', [ConfigValueError('operation.hook_load_n', 'must be >= 0'),
                                   ConfigError('--set', 'operation.hook_load_n', 'must be >= 0')])
def test_configuration_errors_survive_pickling(error):
    """A map point's error crosses from its worker process intact (not a broken pool)."""
    again = pickle.loads(pickle.dumps(error))
    assert type(again) is type(error) and str(again) == str(error)
    assert (again.key, again.message) == ('operation.hook_load_n', 'must be >= 0')


def test_missing_key_in_a_replacing_list():
    section = dict(default_raw()['sections'][0])
    del section['elements']
    with pytest.raises(ConfigError, match='sections.drill_pipe.elements: missing key'):
        config_with({'sections': [section]})


def test_unknown_set_key_is_an_error():
    with pytest.raises(ConfigError, match=r'--set: fluid\.viscosity: unknown key'):
        load_config(None, ['fluid.viscosity=3'])


def _run_cli(*args):
    return subprocess.run([sys.executable, '-m', 'drill_twin.cli.main', *args],
                          capture_output=True, text=True, cwd=REPO, timeout=120)


@pytest.mark.parametrize('content, expected', [
    ('fluid:\n  density_kg_per_m3: -5\n',
     'bad.yaml: fluid.density_kg_per_m3: must be a finite positive'),
    ('fluid: [1, 2\n', 'bad.yaml: line 2: YAML syntax error'),
    ('- just\n- a list\n', 'bad.yaml: the file must hold a mapping'),
    ('sections:\n  - name: x\n', 'bad.yaml: sections.x.kind: missing key'),
])
def test_cli_reports_one_line_and_exit_status_2(tmp_path, content, expected):
    path = tmp_path / 'bad.yaml'
    path.write_text(content)
    result = _run_cli('modes', '--config', str(path))
    assert result.returncode == 2
    assert result.stdout == ''
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert 'Traceback' not in result.stderr
    assert expected in lines[0]


def test_cli_names_set_as_the_source_of_a_bad_value():
    result = _run_cli('modes', '--set', 'borehole.diameter_m=0.1')
    assert result.returncode == 2
    assert result.stderr.strip().startswith('drill-twin: --set: ')
    assert 'does not fit in the borehole' in result.stderr


def test_cli_missing_file():
    result = _run_cli('modes', '--config', '/nonexistent/drill.yaml')
    assert result.returncode == 2
    assert result.stderr.strip() == ('drill-twin: /nonexistent/drill.yaml: cannot read: '
                                     'No such file or directory')


@pytest.mark.parametrize('content, words', [
    (b'\xe4\x00\xff binary', 'not a UTF-8 text file (byte 0xe4 at offset 0)'),
    (b'a: ' + b'[' * 5000, 'YAML'),
    (b'# ' + b'x' * (1 << 20) + b'\n', 'larger than 1024 KiB: not a configuration file'),
])
def test_files_that_are_not_configurations_are_one_line(tmp_path, content, words):
    path = tmp_path / 'odd.yaml'
    path.write_bytes(content)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert str(info.value).startswith(f'{path}: ') and '\n' not in str(info.value)
    assert words in str(info.value)


@pytest.mark.parametrize('override', ['sections.1.length_m=-5',
                                      'sections.drill_collar.length_m=-5'])
def test_a_bad_list_item_is_blamed_on_set_by_index_or_name(override):
    with pytest.raises(ConfigError) as info:
        load_config(None, [override])
    assert info.value.source == '--set'
    assert info.value.key == 'sections.drill_collar.length_m'


def test_a_bad_value_from_the_file_is_not_blamed_on_an_unrelated_set(tmp_path):
    path = tmp_path / 'mine.yaml'
    path.write_text('fluid:\n  density_kg_per_m3: 9000.0\n')
    with pytest.raises(ConfigError) as info:
        load_config(path, ['sections.1.elements=30'])
    assert info.value.source == str(path)
    assert info.value.key == 'fluid.density_kg_per_m3'
    assert 'heaviest drilling muds' in info.value.message


def test_the_lateral_profile_is_the_paper_with_an_imbalance(default_config):
    """
    The lateral profile: the paper's string and point, m e = 50 kg m.

    config/ritto2009_lateral.yaml, docs/LATERAL.md "The lateral profile".
    """
    profile = load_config(REPO / 'config' / 'ritto2009_lateral.yaml')
    imbalance = profile.excitation.imbalance
    assert imbalance.enabled
    assert imbalance.mass_kg * imbalance.eccentricity_m == pytest.approx(50.0)
    assert imbalance.position_m == 1500.0
    ours, paper = config_to_dict(profile), config_to_dict(default_config)
    assert {k for k in ours if ours[k] != paper[k]} == {'excitation'}


def test_the_bit_bounce_profile_is_the_lateral_profile_on_lobes():
    """config/ritto2009_bit_bounce.yaml: the lateral profile on a three-lobed bottom of 1.8 mm."""
    profile = load_config(REPO / 'config' / 'ritto2009_bit_bounce.yaml')
    lateral = load_config(REPO / 'config' / 'ritto2009_lateral.yaml')
    pattern = profile.excitation.bottom_hole_pattern
    assert pattern.enabled and pattern.lobes == 3 and pattern.amplitude_m == 0.0018
    assert profile.excitation.imbalance == lateral.excitation.imbalance
    ours, theirs = config_to_dict(profile), config_to_dict(lateral)
    assert {k for k in ours if ours[k] != theirs[k]} == {'excitation'}
