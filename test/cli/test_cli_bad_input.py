"""
Bad input to the command line.

One line ``drill-twin: ...`` naming the file or option, the key and the problem, and exit status
2; never a traceback (issue 9, item 5).

One case per class of bad input, each through the real command in a subprocess.
"""
from __future__ import annotations

import subprocess
import sys

import pytest
from cli_output import assert_one_line

MONTECARLO = ('montecarlo', '--delta', '0.01', '--samples', '2', '--out', 'study')


def run_cli(*args, cwd):
    return subprocess.run([sys.executable, '-m', 'drill_twin.cli.main', *args],
                          capture_output=True, text=True, cwd=cwd, timeout=600,
                          stdin=subprocess.DEVNULL)


@pytest.mark.parametrize('kind', ['binary', 'directory'])
def test_a_config_that_is_not_a_text_file(tmp_path, kind):
    path = tmp_path / 'config.yaml'
    if kind == 'binary':
        path.write_bytes(bytes(range(256)) * 4)
        words = (f'{path}: not a UTF-8 text file (byte 0x80 at offset 128)',)
    else:
        path.mkdir()
        words = (f'{path}: cannot read: Is a directory',)
    assert_one_line(run_cli('modes', '--config', str(path), cwd=tmp_path), *words)


@pytest.mark.parametrize('override, words', [
    # Finite, but beyond anything physical; the model built from it would overflow.
    ('gravity_m_per_s2=1e308', ('--set: gravity_m_per_s2: must be at most 30',)),
    ('sections.drill_pipe.young_modulus_pa=1e308',
     ('--set: sections.drill_pipe.young_modulus_pa: must be at most 1.2e+12',)),
    # A list item by index is blamed on --set under its name, not on the built-in file.
    ('sections.1.length_m=-5', ('--set: sections.drill_collar.length_m: must be a finite',)),
    # Accepted by the schema, but no model can be built from it: the source is named.
    ('reduced_basis.lateral_modes=100000',
     ('ritto2009.yaml with --set reduced_basis.lateral_modes=100000: the model cannot be '
      'built from it: reduced_basis.lateral_modes: asked for 100000',)),
])
def test_implausible_configuration_values(tmp_path, override, words):
    assert_one_line(run_cli('modes', '--set', override, cwd=tmp_path), *words)


@pytest.mark.parametrize('value, words', [
    ('-5', '--count: must be at least 1, got -5'),
    ('five', "argument --count: invalid int value: 'five' (see drill-twin modes --help)"),
])
def test_a_mode_count_that_is_not_a_positive_integer(tmp_path, value, words):
    assert_one_line(run_cli('modes', '--count', value, cwd=tmp_path), words)


@pytest.mark.parametrize('args, words', [
    (('simulate', '--duration', 'inf'), ('--duration: must be positive and finite',)),
    (('simulate', '--duration', '1e7'),
     ('--duration: 1e+07 s recorded every 0.01 s (1e+09 records) would need', 'GiB of memory')),
    (MONTECARLO + ('--duration', 'nan'), ('--duration: must be positive and finite',)),
    (MONTECARLO + ('--duration', '10', '--workers', '100000'), ('--workers: must lie in 1',)),
    (('twin', '--no-log', '--duration', 'inf'), ('--duration: must be positive and finite',)),
], ids=['simulate-inf', 'simulate-1e7', 'montecarlo-nan', 'montecarlo-workers', 'twin-inf'])
def test_durations_and_sizes_that_cannot_run(tmp_path, args, words):
    assert_one_line(run_cli(*args, cwd=tmp_path), *words)


@pytest.mark.parametrize('args, words', [
    (('simulate', '--duration', '5', '--set', 'bit_rock.a1_m_per_s=10'),
     ('--set: bit_rock: the law gives a steady ROP of -8.71 m/s', 'push the bit back up')),
    (('simulate', '--duration', '5', '--set', 'bit_rock.a4_n_rad=1e12'),
     ('--set: bit_rock: the law gives a steady torque on bit of -4.39e+08 N m',
      'more than the string carries')),
    (MONTECARLO + ('--duration', '5', '--set', 'bit_rock.a2_m_per_n_s=1.0'),
     ('--set: bit_rock: the law gives a steady ROP of 8.72e+04 m/s', 'faster than any')),
    (('twin', '--no-log', '--duration', '1', '--set', 'bit_rock.a2_m_per_n_s=1.0'),
     ('--set: bit_rock: the law gives a steady ROP of 8.72e+04 m/s',)),
], ids=['simulate-a1', 'simulate-a4', 'montecarlo-a2', 'twin-a2'])
def test_a_configuration_that_cannot_be_integrated_is_refused_at_start(tmp_path, args, words):
    assert_one_line(run_cli(*args, cwd=tmp_path), *words)
    assert not (tmp_path / 'study').exists()


def test_a_run_that_diverges_after_the_preflight_is_one_line(tmp_path):
    """
    A Newton failure at the run's first step is caught by the command, not the check.

    The pre-flight's short run is shortened to nothing, so that the run itself meets the
    failure of a Newton solve allowed one iteration at an unreachable tolerance (even on
    sub-steps down to dt/16) at its first step: the command catches it, not the check.
    """
    code = ('import sys\n'
            'import drill_twin.analysis.preflight as preflight\n'
            'preflight.SHORT_RUN_S = 0.0\n'
            'from drill_twin.cli.main import main\n'
            'sys.exit(main(["simulate", "--duration", "1", "--set", '
            '"integration.max_iterations=1", "--set", "integration.tolerance=1e-14"]))\n')
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            cwd=tmp_path, timeout=600)
    assert_one_line(result, 'with --set integration.max_iterations=1 --set '
                            'integration.tolerance=1e-14: the run cannot be integrated: '
                            'no convergence in 1 iterations at t = 0.005 s',
                            'members [0] failed on sub-steps down to dt/16 too')
