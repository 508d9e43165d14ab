"""Regenerate docs/figures/rerun_<tab>.png: each tab of ``drill-twin view`` in the real viewer.

    python docs/figures/make_screenshots.py LOG [--out docs/figures] [--tool rerun-screenshot]

LOG is a twin log (a .mcap file or a bag directory), e.g. from
``drill-twin twin --fast --duration 30 --log-dir /tmp/runs``.  The log is converted once
(:func:`drill_twin.viz.rerun_view.save_rrd`); for every tab a blueprint (.rbl) with
that tab active is written and the screenshot tool (``rerun-screenshot INPUT.rrd
LAYOUT.rbl OUT.png``: rerun on a virtual screen with a software renderer) saves what a user
sees.  The tool is CPU heavy: the tabs are taken one at a time.
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile

HERE = Path(__file__).resolve().parent


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('log', nargs='+', help='a twin log (.mcap, bag directory, split files)')
    parser.add_argument('--out', type=Path, default=HERE, help='where the PNGs go')
    parser.add_argument('--tool', default=os.environ.get('RERUN_SCREENSHOT', 'rerun-screenshot'),
                        help='the screenshot tool (default: $RERUN_SCREENSHOT or '
                             'rerun-screenshot on PATH)')
    parser.add_argument('--tabs', nargs='+', default=None, help='only these tabs')
    args = parser.parse_args(argv)

    from drill_twin.viz.rerun_blueprint import twin_blueprint
    from drill_twin.viz.rerun_entities import APPLICATION_ID, TABS
    from drill_twin.viz.rerun_native import geometry_of
    from drill_twin.viz.run_columns import log_files, read_run
    from drill_twin.viz.rerun_view import rerun_executable, save_rrd

    tool = shutil.which(args.tool) or args.tool
    if not Path(tool).is_file():
        print(f'make_screenshots: no screenshot tool {args.tool!r} (--tool PATH)',
              file=sys.stderr)
        return 2
    tabs = args.tabs or list(TABS)
    files = log_files(args.log)
    geometry = geometry_of(read_run(files))
    args.out.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, RERUN=os.environ.get('RERUN', rerun_executable()),
               WAIT=os.environ.get('WAIT', '120'))      # a loaded machine is slow
    with tempfile.TemporaryDirectory(prefix='drill_twin_shots_') as directory:
        rrd = save_rrd(files, Path(directory) / 'run.rrd')
        for tab in tabs:
            blueprint = Path(directory) / f'{tab}.rbl'
            twin_blueprint(geometry, active_tab=tab).save(APPLICATION_ID, blueprint)
            out = args.out / f'rerun_{tab}.png'
            subprocess.run([tool, str(rrd), str(blueprint), str(out)], env=env, check=True)
            print(out)
    return 0


if __name__ == '__main__':
    sys.exit(main())
