#!/usr/bin/env python3
"""
Make a Python environment an ament prefix for drill_twin after an editable install.

    python scripts/link_ament_files.py PREFIX [--activate]

An editable install (``pip install -e``, which ``make setup`` does) leaves out setup.py's
``data_files``: no ``share/ament_index`` marker, no ``share/drill_twin`` and no
``lib/drill_twin/twin``, so ``get_package_share_directory('drill_twin')`` and ``ros2 run`` /
``ros2 launch`` cannot find the package. This places setup.py's ``DATA_FILES`` (the one list)
into PREFIX: the shared files as links into the source tree (edits show at once), the
``ros2 run`` launcher as a copy whose first line runs PREFIX's Python. With ``--activate``,
PREFIX/bin/activate also puts PREFIX on ``AMENT_PREFIX_PATH``, as sourcing a ROS workspace's
setup.bash does.
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import runpy
import sys

REPO = Path(__file__).resolve().parents[1]
ACTIVATE_LINE = 'export AMENT_PREFIX_PATH="$VIRTUAL_ENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"'
ACTIVATE_MARK = '# drill_twin: this environment is an ament prefix'


def data_files() -> list[tuple[str, list[str]]]:
    """setup.py's DATA_FILES, read without running setup() (paths relative to the repository)."""
    cwd = os.getcwd()
    os.chdir(REPO)
    try:
        return runpy.run_path(str(REPO / 'setup.py'), run_name='drill_twin_setup')['DATA_FILES']
    finally:
        os.chdir(cwd)


def place(prefix: Path) -> list[Path]:
    """Put every data file into ``prefix``; return the paths written."""
    written = []
    for destination, sources in data_files():
        folder = prefix / destination
        folder.mkdir(parents=True, exist_ok=True)
        for source in sources:
            target = folder / Path(source).name
            if target.is_symlink() or target.exists():
                target.unlink()
            if destination.startswith('lib/'):
                lines = (REPO / source).read_text().splitlines(keepends=True)
                python = prefix.resolve() / 'bin' / 'python'
                target.write_text(f'#!{python}\n' + ''.join(lines[1:]))
                target.chmod(0o755)
            else:
                target.symlink_to(REPO / source)
            written.append(target)
    return written


def add_to_activate(prefix: Path) -> None:
    """Append the AMENT_PREFIX_PATH export to ``prefix``/bin/activate (once)."""
    activate = prefix / 'bin' / 'activate'
    text = activate.read_text()
    if ACTIVATE_MARK not in text:
        activate.write_text(text.rstrip('\n') + f'\n\n{ACTIVATE_MARK}\n{ACTIVATE_LINE}\n')


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('prefix', type=Path)
    parser.add_argument('--activate', action='store_true',
                        help='also put PREFIX on AMENT_PREFIX_PATH in PREFIX/bin/activate')
    args = parser.parse_args(argv)
    if args.activate and not (args.prefix / 'bin' / 'activate').is_file():
        parser.error(f'--activate: no {args.prefix / "bin" / "activate"}')
    written = place(args.prefix)
    if args.activate:
        add_to_activate(args.prefix)
    print(f'{args.prefix}: {len(written)} ament files in place')
    return 0


if __name__ == '__main__':
    sys.exit(main())
