"""Speed-up of this checkout over an earlier revision, measured in alternating processes.

    python benchmarks/speedup.py [REVISION] [--rounds 4] [--seconds 3] [--members 1 16]

REVISION (default BASELINE: the last revision before the compiled kernels) is
checked out into a temporary git worktree. Each round runs that revision's own
``benchmarks/realtime_factor.py``, then this checkout's, each in a process of its own with
its version first on PYTHONPATH (checked: the process imports the package from there), in
alternating order from round to round. It prints, per round and batch size, both real-time
factors and their ratio, then each batch size's median ratio and range.

Why processes side by side: this VM's speed moves by up to half for seconds to minutes
(``run_all.py``'s docstring), so two figures taken minutes apart compare two machines; a
ratio of runs a few seconds apart compares two codes. Both versions run on this
environment's libraries (numpy, scipy, numba of the virtual environment): an old revision's
figure today can differ from what it measured with the libraries of its day.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

BASELINE = '376657b^'
"""The last revision without compiled kernels: the parent of the commit that added numba
(docs/SPEED.md, "Targets and latest figures", gives the speed-up over it)."""
CHECKOUT = Path(__file__).resolve().parents[1]


def realtime_factors(text: str) -> dict[int, float]:
    """
    Return {members: RTF} from realtime_factor.py's table.

    Its rows: members, dt [ms], wall/sim s, RTF, member-RTF, evals/step.
    """
    factors = {}
    for line in text.splitlines():
        fields = line.split()
        if len(fields) != 6 or not fields[0].isdigit():
            continue
        try:
            factors[int(fields[0])] = float(fields[3])
        except ValueError:
            continue
    return factors


def run(version: Path, seconds: float, members: list[int]) -> dict[int, float]:
    """Run ``version``'s realtime_factor.py in a process of its own; {members: RTF}."""
    environment = dict(os.environ, PYTHONPATH=str(version))
    imported = subprocess.run(
        [sys.executable, '-c', 'import drill_twin; print(drill_twin.__file__)'],
        env=environment, cwd=version, capture_output=True, text=True, check=True).stdout
    if not Path(imported.strip()).resolve().is_relative_to(version.resolve()):
        raise SystemExit(f'{version}: the process imports drill_twin from {imported.strip()}')
    output = subprocess.run(
        [sys.executable, 'benchmarks/realtime_factor.py', '--seconds', str(seconds),
         '--members', *map(str, members)],
        env=environment, cwd=version, capture_output=True, text=True, check=True).stdout
    factors = realtime_factors(output)
    missing = set(members) - set(factors)
    if missing:
        raise SystemExit(f'{version}: no RTF for {sorted(missing)} members in:\n{output}')
    return factors


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('revision', nargs='?', default=BASELINE,
                        help=f'the earlier revision (default {BASELINE})')
    parser.add_argument('--rounds', type=int, default=4)
    parser.add_argument('--seconds', type=float, default=3.0,
                        help='simulated seconds per batch size and run')
    parser.add_argument('--members', type=int, nargs='+', default=[1, 16])
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix='drill_twin-speedup-') as folder:
        earlier = Path(folder) / 'earlier'
        added = subprocess.run(['git', 'worktree', 'add', '--detach', str(earlier),
                                args.revision], cwd=CHECKOUT, capture_output=True, text=True)
        if added.returncode != 0:
            parser.error(f'revision {args.revision!r}: {added.stderr.strip().splitlines()[-1]}')
        try:
            commit = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=earlier,
                                    check=True, capture_output=True, text=True).stdout.strip()
            print(f'{args.revision} ({commit}) against this checkout ({CHECKOUT}), '
                  f'{args.seconds:g} s of model time per run, {args.rounds} rounds')
            print(f'{"round":>5} {"members":>8} {"RTF then":>9} {"RTF now":>9} {"ratio":>7}')
            ratios = {m: [] for m in args.members}
            for round_ in range(args.rounds):
                order = (earlier, CHECKOUT) if round_ % 2 == 0 else (CHECKOUT, earlier)
                results = {version: run(version, args.seconds, args.members)
                           for version in order}
                for m in args.members:
                    then, now = results[earlier][m], results[CHECKOUT][m]
                    ratios[m].append(now / then)
                    print(f'{round_ + 1:>5} {m:>8} {then:>9.2f} {now:>9.2f} '
                          f'{now / then:>7.2f}', flush=True)
        finally:
            subprocess.run(['git', 'worktree', 'remove', '--force', str(earlier)],
                           cwd=CHECKOUT, check=False, capture_output=True)
    for m in args.members:
        r = np.array(ratios[m])
        print(f'{m} member(s): speed-up median {np.median(r):.2f} '
              f'(range {r.min():.2f}-{r.max():.2f})')


if __name__ == '__main__':
    main()
