"""Style as ament's linters check it: flake8 (99 columns) and pep257 docstrings.

The settings are ament_flake8's and ament_pep257's (ROS 2 Jazzy): flake8 with
max-line-length 99 and its extend-ignore list, over the package and the tests (flake8-docstrings
adds the D codes where it is installed); pydocstyle with ament_pep257's ignore list over the
package. ament's flake8 also runs flake8-builtins, -comprehensions, -import-order and -quotes,
which are not installed here. A failure lists every violation, file by file.
"""
from __future__ import annotations

from collections import defaultdict
import subprocess
import sys

from conftest import REPO

AMENT_FLAKE8_IGNORE = ('B902', 'C816', 'D100', 'D101', 'D102', 'D103', 'D104', 'D105', 'D106',
                       'D107', 'D203', 'D212', 'D404', 'I202')
"""extend-ignore of ament_flake8's configuration."""
AMENT_PEP257_IGNORE = ('D100', 'D101', 'D102', 'D103', 'D104', 'D105', 'D106', 'D107', 'D203',
                       'D212', 'D404')
"""ament_pep257's default ignore list."""


def _by_file(lines: list[str]) -> str:
    """Violations 'path:line:col: CODE text' grouped by file, with counts."""
    files = defaultdict(list)
    for line in lines:
        files[line.split(':', 1)[0]].append(line)
    return '\n'.join(f'{path}: {len(found)} violation(s)\n  ' + '\n  '.join(found)
                     for path, found in sorted(files.items()))


def test_flake8_with_ament_settings():
    result = subprocess.run(
        [sys.executable, '-m', 'flake8', '--max-line-length', '99',
         '--extend-ignore', ','.join(AMENT_FLAKE8_IGNORE), 'drill_twin', 'test'],
        capture_output=True, text=True, cwd=REPO, timeout=600)
    assert result.returncode in (0, 1), result.stderr
    found = [line for line in result.stdout.splitlines() if line.strip()]
    assert not found, f'{len(found)} flake8 violation(s):\n' + _by_file(found)


def test_pep257_docstrings_with_ament_settings():
    result = subprocess.run(
        [sys.executable, '-m', 'pydocstyle', '--ignore', ','.join(AMENT_PEP257_IGNORE),
         'drill_twin'], capture_output=True, text=True, cwd=REPO, timeout=600)
    assert result.returncode in (0, 1), result.stderr
    # pydocstyle prints 'path:line in object:' then an indented 'CODE: text' line.
    lines = result.stdout.splitlines()
    found = [f'{where.split(" ", 1)[0]}: {text.strip()}'
             for where, text in zip(lines[::2], lines[1::2])]
    assert not found, f'{len(found)} pep257 violation(s):\n' + _by_file(found)
