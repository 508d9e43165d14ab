"""
Bad input to the command line.

One line ``drill-twin: ...`` naming the file or option, the key and the problem, and exit status
2; never a traceback.

One case per class of bad input, each through the real command in a subprocess.
"""
from __future__ import annotations

from pathlib import Path
import subprocess
import sys

from mcap.writer import Writer
import pytest
from cli_output import assert_one_line

MONTECARLO = ('montecarlo', '--delta', '0.01', '--samples', '2', '--out', 'study')
READ_ONLY = Path('/proc')
"""A system directory in which no file can be created, not even by root."""


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


# -- outputs checked before the work -------------------------------------------------------

def _empty_mcap(path: Path) -> Path:
    """Write a complete MCAP file without messages (a log the commands accept as input)."""
    with open(path, 'wb') as stream:
        writer = Writer(stream)
        writer.start()
        writer.finish()
    return path


def _leftovers(folder: Path) -> list[str]:
    """Names in ``folder`` that a refused command may have left (probe files, outputs)."""
    inputs = ('log.mcap', 'file', 'figure.png')
    return sorted(p.name for p in folder.iterdir() if p.name not in inputs)


@pytest.mark.parametrize('args, words', [
    (('simulate', '--duration', '1', '--out', str(READ_ONLY / 'x.csv')),
     ('--out: cannot create a file in /proc',)),
    (('simulate', '--duration', '1', '--summary', 'missing/s.json'),
     ('--summary: missing: no such directory',)),
    (('simulate', '--duration', '1', '--summary', 'file/s.json'),
     ('--summary: file is a file, not a directory',)),
    (('simulate', '--duration', '1', '--plot', 'figure.png'),
     ('--plot: figure.png is a directory; name a file',)),
    (('simulate', '--duration', '1', '--plot', 'run.txt'),
     ('--plot: run.txt: use a .png, ',)),
    (('simulate', '--duration', '1', '--out', 'run.csv', '--summary', 'run.csv'),
     ('--summary: run.csv is also --out; name another file',)),
    (MONTECARLO[:-1] + ('file', '--duration', '1'), ('--out: file is a file, not a directory',)),
    (MONTECARLO[:-1] + (str(READ_ONLY / 'study'), '--duration', '1'),
     ('--out: cannot create a file in /proc',)),
    (('map', '--speeds', '5', '--weights-on-bit', '1e5', '--out', 'file/map'),
     ('--out: file is a file, not a directory',)),
    (('rig', '--out', str(READ_ONLY / 'rig.mcap')), ('--out: cannot create a file in /proc',)),
    (('assimilate', 'log.mcap', '--out', str(READ_ONLY / 'est.mcap')),
     ('--out: cannot create a file in /proc',)),
    (('assimilate', 'log.mcap', '--out', 'est.mcap', '--summary', 'missing/s.json'),
     ('--summary: missing: no such directory',)),
    (('assimilate', 'log.mcap', '--out', 'log.mcap'), ('--out: log.mcap is also LOG',)),
    (('recover', 'log.mcap', '--out', str(READ_ONLY / 'fixed.mcap')),
     ('--out: cannot create a file in /proc',)),
    (('view', 'log.mcap', '--rrd', str(READ_ONLY / 'v.rrd')),
     ('--rrd: cannot create a file in /proc',)),
    (('view', 'log.mcap', '--rrd', 'v.txt'), ('--rrd: v.txt: use a .rrd file name',)),
], ids=['simulate-read-only', 'simulate-missing-directory', 'simulate-parent-is-a-file',
        'simulate-plot-is-a-directory', 'simulate-plot-format', 'simulate-same-file',
        'montecarlo-existing-file', 'montecarlo-read-only', 'map-parent-is-a-file',
        'rig-read-only', 'assimilate-read-only', 'assimilate-summary-missing-directory',
        'assimilate-over-its-log', 'recover-read-only', 'view-read-only', 'view-format'])
def test_outputs_that_cannot_be_written_are_refused_before_the_work(tmp_path, args, words):
    """
    Each output option is checked first: one line naming it, and nothing written.

    Without the check each command runs its whole computation, then fails with a traceback
    (or, for view, writes a file of another format).
    """
    _empty_mcap(tmp_path / 'log.mcap')
    (tmp_path / 'file').write_text('a file where a directory is wanted\n')
    (tmp_path / 'figure.png').mkdir()
    assert_one_line(run_cli(*args, cwd=tmp_path), *words)
    assert _leftovers(tmp_path) == []


# -- bounds on what no run can finish -------------------------------------------------------

MAP = ('map', '--out', 'map', '--speeds', '5', '--weights-on-bit', '1e5')


@pytest.mark.parametrize('args, words', [
    (('simulate', '--duration', '1', '--set', 'integration.time_step_s=1e-9'),
     ('--set: integration.time_step_s: must be at least 1e-05 (a step takes about 0.2 ms',
      'got 1e-09')),
    (('twin', '--no-log', '--duration', '1', '--ros-args', '-p', 'time_step_s:=1e-9'),
     ('--ros-args -p: time_step_s: must be at least 1e-05 (a step takes', 'got 1e-09')),
    (MAP + ('--duration', 'inf'), ('--duration: must be positive and finite',)),
    (('map', '--out', 'map', '--speeds', '1:20:1000000', '--weights-on-bit', '1e4:2e5:1000000'),
     ('--speeds, --weights-on-bit: a grid of 1000000 x 1000000 = 1e+12 points would need',
      'of memory')),
    (('map', '--out', 'map', '--speeds', '1:20:1000000000000', '--weights-on-bit', '1e5'),
     ("--speeds: '1:20:1000000000000': 1000000000000 values would need", 'of memory')),
    (MAP + ('--duration', '1e9', '--window', '1e9'),
     ('--window: 1e+09 s at 0.005 s per step', 'would need', 'of memory')),
    (('rig', '--out', 'rig.mcap', '--duration', '1e8'),
     ('--duration: 1e+08 s of rig log (4.02e+09 samples) would need', 'of memory')),
], ids=['simulate-time-step', 'twin-time-step', 'map-duration-inf', 'map-grid',
        'map-range', 'map-window', 'rig-duration'])
def test_runs_that_cannot_finish_are_refused_at_once(tmp_path, args, words):
    """A step below the stated minimum, a grid or a window beyond memory: one line, no output."""
    assert_one_line(run_cli(*args, cwd=tmp_path), *words)
    assert list(tmp_path.iterdir()) == []


# -- a log that is not MCAP ------------------------------------------------------------------

@pytest.mark.parametrize('command', [
    ('replay', 'LOG'), ('replay', 'LOG', '--resimulate'), ('view', 'LOG', '--rrd', 'v.rrd'),
    ('recover', 'LOG', '--out', 'fixed.mcap'), ('assimilate', 'LOG', '--out', 'est.mcap')],
    ids=['replay', 'resimulate', 'view', 'recover', 'assimilate'])
@pytest.mark.parametrize('log', ['text', 'empty', 'bag'])
def test_a_log_that_is_not_mcap_is_exit_2(tmp_path, command, log):
    """
    A file without the MCAP magic, or a bag directory without an MCAP file: one line.

    replay and view --rrd read such a file as a log of no messages and succeeded.
    """
    if log == 'bag':
        path = tmp_path / 'run'
        path.mkdir()
        (path / 'run_0.mcap').write_text('not a log\n')
        words = (f'{path}: no MCAP files in it (not a log)',)
    else:
        path = tmp_path / 'run.mcap'
        path.write_text('not a log\n' if log == 'text' else '')
        words = (f'{path}: not an MCAP file (' + ('empty)' if log == 'empty'
                                                  else 'no MCAP magic at its start)'),)
    if command[0] == 'recover' and log == 'bag':
        words = (f'{path}: not a file (recover one split of a bag)',)
    args = [str(path) if item == 'LOG' else item for item in command]
    assert_one_line(run_cli(*args, cwd=tmp_path), *words)
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]
