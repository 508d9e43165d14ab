#!/usr/bin/env python3
"""
Regenerate the figures and tables of docs/results, each with a MANIFEST.json beside it.

    .venv/bin/python scripts/make_results.py [NAME ...] [--root DIR] [--list]
                                             [--mean-model-duration S]

NAME is a directory of docs/results (``table1``, ``mean_model``, ``map``,
``montecarlo_delta_0.01``, ``lateral/montecarlo_delta_0.1``, ``drives``, ...) or a group:
``results`` (Table 1, the mean model and the map: what ``make results`` runs), ``montecarlo``,
``lateral``, ``drives``, ``all``. Every directory is written by shell commands run from the
repository root with the virtual environment's ``bin`` first on PATH (``drill-twin``,
``python``); the commands are recorded in the MANIFEST as they ran, so that a user can repeat
one by hand. ``--root`` writes the directories under another root instead of docs/results
(the tests use a temporary one). docs/results/README.md lists the directories and the
MANIFEST's keys.

The configuration hash is :func:`config_hash`: SHA-256 of the complete configuration as
canonical JSON (keys sorted, separators ``,`` and ``:``, UTF-8). Each directory keeps the
complete configuration it ran with as ``config.yaml`` (written by ``drill-twin map`` and
``drill-twin montecarlo`` themselves, by this script for the other commands), so the hash can
be checked against the file beside it.
"""
from __future__ import annotations

import argparse
import dataclasses
import datetime
import hashlib
import json
import os
from pathlib import Path
import shlex
import subprocess
import sys
from typing import Callable

import yaml

from drill_twin.config import load_config
from drill_twin.config.loader import config_to_dict

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / 'docs' / 'results'
DEFAULT_CONFIG = 'config/ritto2009.yaml'
LATERAL_CONFIG = 'config/ritto2009_lateral.yaml'
SOURCE_PATHS = ('drill_twin', 'config', 'benchmarks', 'scripts', 'setup.py', 'setup.cfg')
"""What the results depend on: a change here not yet committed makes ``source_modified``."""

MONTECARLO_FIGURES = ('fig07_convergence.png', 'fig08_rop.png', 'fig09a_weight_on_bit.png',
                      'fig09b_torque_on_bit.png', 'fig10_bit_speed.png',
                      'fig11_radial_displacement.png', 'fig16_rop_realizations.png')
MEAN_MODEL_WINDOW_S = 50.0
"""The paper's stationary window, 200-250 s of a 250 s run."""


def config_hash(config: dict) -> str:
    """
    Return the configuration hash recorded in a MANIFEST.

    :param config: the complete configuration as a plain mapping (what ``config.yaml`` holds,
        :func:`drill_twin.config.loader.config_to_dict` of the loaded configuration).
    :returns: SHA-256 (64 hex digits) of its canonical JSON: keys sorted, separators ``,``
        and ``:``, UTF-8, floats in Python's shortest round-trip form.
    """
    text = json.dumps(config, sort_keys=True, separators=(',', ':'), ensure_ascii=False)
    return hashlib.sha256(text.encode('utf-8')).hexdigest()


@dataclasses.dataclass(frozen=True)
class Study:
    """
    One directory of docs/results and the commands that write it.

    :param name: the directory relative to the results root (also its name on the command line).
    :param groups: the groups that include it (``results``, ``montecarlo``, ...).
    :param commands: the shell lines, given the output directory as the command line spells
        it (relative to the repository root when inside it).
    :param files: the files the directory keeps (what a document cites; the rest, raw arrays,
        is left on disk and ignored by git).
    :param config: the configuration file given to the command.
    :param seed: the seed of the random draws, None for a deterministic run.
    :param writes_config: the command writes ``config.yaml`` itself.
    """

    name: str
    groups: tuple[str, ...]
    commands: Callable[[str], list[str]]
    files: tuple[str, ...]
    config: str = DEFAULT_CONFIG
    seed: int | None = None
    writes_config: bool = False


def _modes(out: str) -> list[str]:
    return [f'drill-twin modes > {out}/table1.txt',
            f'drill-twin modes --json > {out}/modes.json']


def _mean_model(duration_s: float) -> Callable[[str], list[str]]:
    window_s = min(MEAN_MODEL_WINDOW_S, duration_s)

    def commands(out: str) -> list[str]:
        return [f'drill-twin simulate --duration {duration_s:g} --window {window_s:g} '
                f'--summary {out}/summary.json --plot {out}/mean_model.png']
    return commands


def _map(out: str) -> list[str]:
    return ['drill-twin map --speeds 2,3,4,5.215,7,10,14,20 --weights-on-bit 50e3:250e3:5 '
            f'--duration 100 --window 20 --workers 1 --out {out}']


def _montecarlo(delta: float, samples: int, config: str | None) -> Callable[[str], list[str]]:
    option = f'--config {config} ' if config else ''

    def commands(out: str) -> list[str]:
        return [f'drill-twin montecarlo {option}--delta {delta:g} --samples {samples} '
                f'--duration 250 --window 50 --seed 2009 --workers 2 --out {out}']
    return commands


FULL_MODEL = ('--set physics.contact=true --set physics.kinetic_coupling=true '
              '--set physics.finite_strain=true --set reduced_basis.lateral_modes=158 '
              '--set initial_conditions.lateral_deflection_m=0.05')
TUNED_IMPEDANCE = ('--set top_drive.impedance_nm_s_per_rad=600 '
                   '--set top_drive.mean_torque_time_constant_s=100')


def _drives(out: str) -> list[str]:
    bench = 'python benchmarks/drive_controllers.py'
    full = f'{out}/full_model'
    return [
        f'{bench} {out}',
        f'{bench} {out} --drives impedance {TUNED_IMPEDANCE} --label impedance_c600_tau100 '
        '--append',
        f'rm -rf {full}',
        *(f'{bench} {full} --wob-kn 100 150 --speed-hz 0.83 --drives {drive} {FULL_MODEL} '
          f'--label full_{drive} --append' for drive in ('stiff', 'impedance', 'soft_torque')),
        f'{bench} {full} --wob-kn 150 --speed-hz 0.83 --drives impedance {FULL_MODEL} '
        f'{TUNED_IMPEDANCE} --label full_impedance_c600_tau100 --append',
        f'mv {full}/drive_controllers.csv {out}/drive_controllers_full_model.csv',
        f'rm -rf {full}',
    ]


def studies(mean_model_duration_s: float = 250.0) -> dict[str, Study]:
    """Return every directory this script writes, by name."""
    montecarlo_files = ('summary.json', 'convergence.csv') + MONTECARLO_FIGURES
    found = [
        Study('table1', ('results',), _modes, ('table1.txt', 'modes.json')),
        Study('mean_model', ('results',), _mean_model(mean_model_duration_s),
              ('mean_model.png', 'summary.json')),
        Study('map', ('results',), _map,
              ('map.png', 'map.csv', 'map.json', 'linear_stability.csv'),
              writes_config=True),
        Study('drives', ('drives',), _drives,
              ('drive_controllers.png', 'drive_controllers.csv',
               'drive_controllers_full_model.csv')),
    ]
    for delta in (0.001, 0.01, 0.1):
        found.append(Study(f'montecarlo_delta_{delta:g}', ('montecarlo',),
                           _montecarlo(delta, 150, None), montecarlo_files, seed=2009,
                           writes_config=True))
    for delta in (0.001, 0.01, 0.1):
        found.append(Study(f'lateral/montecarlo_delta_{delta:g}', ('lateral',),
                           _montecarlo(delta, 50, LATERAL_CONFIG), montecarlo_files,
                           config=LATERAL_CONFIG, seed=2009, writes_config=True))
    return {study.name: study for study in found}


def select(names: list[str], known: dict[str, Study]) -> list[Study]:
    """Return the studies named (directories or groups), in the order of ``known``."""
    wanted = set()
    for name in names:
        members = [s.name for s in known.values() if name == 'all' or name in s.groups]
        if name in known:
            members = [name]
        if not members:
            raise SystemExit(f'make_results: no result or group {name!r} '
                             f'(--list names them)')
        wanted.update(members)
    return [study for name, study in known.items() if name in wanted]


def _spelled(directory: Path) -> str:
    """Return the directory as a command line spells it: relative to the root when inside."""
    try:
        return shlex.quote(str(directory.relative_to(ROOT)))
    except ValueError:
        return shlex.quote(str(directory))


def _git(*args: str) -> str:
    return subprocess.run(['git', *args], cwd=ROOT, check=True, capture_output=True,
                          text=True).stdout.strip()


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def run(study: Study, root: Path) -> dict:
    """Run a study's commands into ``root/study.name`` and write its MANIFEST.json."""
    directory = root / study.name
    directory.mkdir(parents=True, exist_ok=True)
    commands = study.commands(_spelled(directory))
    environment = dict(os.environ)
    environment['PATH'] = str(Path(sys.executable).parent) + os.pathsep + environment['PATH']
    for line in commands:
        print(f'+ {line}', flush=True)
        subprocess.run(['bash', '-o', 'pipefail', '-c', line], cwd=ROOT, env=environment,
                       check=True)
    config = config_to_dict(load_config(ROOT / study.config))
    written = directory / 'config.yaml'
    if study.writes_config:
        if config_hash(yaml.safe_load(written.read_text())) != config_hash(config):
            raise SystemExit(f'make_results: {written} is not the configuration of '
                             f'{study.config}')
    else:
        written.write_text(yaml.safe_dump(config, sort_keys=False))
    missing = [name for name in study.files if not (directory / name).is_file()]
    if missing:
        raise SystemExit(f'make_results: {study.name}: the commands wrote no {missing}')
    manifest = {
        'command': commands,
        'commit': _git('rev-parse', 'HEAD'),
        'source_modified': bool(_git('status', '--porcelain', '--', *SOURCE_PATHS)),
        'config': study.config,
        'config_sha256': config_hash(config),
        'seed': study.seed,
        'date': datetime.datetime.now(datetime.timezone.utc).isoformat(timespec='seconds'),
        'files': {name: _sha256(directory / name)
                  for name in sorted(study.files + ('config.yaml',))},
    }
    (directory / 'MANIFEST.json').write_text(json.dumps(manifest, indent=2) + '\n')
    return manifest


def main(argv: list[str] | None = None) -> int:
    """Parse the command line, regenerate the named directories; return the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('names', nargs='*', default=['results'], metavar='NAME',
                        help='directories or groups (default: results)')
    parser.add_argument('--root', type=Path, default=RESULTS,
                        help='where the directories go (default: docs/results)')
    parser.add_argument('--list', action='store_true', help='list the directories and exit')
    parser.add_argument('--mean-model-duration', type=float, default=250.0, metavar='S',
                        help='simulated time of the mean model (s, default 250; the window '
                             'is the last 50 s or the whole run if shorter)')
    args = parser.parse_args(argv)
    known = studies(args.mean_model_duration)
    if args.list:
        for study in known.values():
            print(f'{study.name:32s} {", ".join(study.groups)}')
        return 0
    for study in select(args.names, known):
        run(study, args.root.resolve())
        print(f'{args.root / study.name}/MANIFEST.json written', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
