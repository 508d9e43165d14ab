"""
Looking at a twin log in rerun (0.41): the ``.rrd`` with the layout, and the viewer.

:func:`save_rrd` converts a log (a ``.mcap`` file, a bag directory or a list of split files)
into one self-contained ``.rrd``: native rerun data on the ``run time`` timeline with the
twin's blueprint (:mod:`~drill_twin.viz.rerun_blueprint`, written by
:mod:`~drill_twin.viz.rerun_native`).  :func:`open_viewer` starts the native viewer on
it, or rerun's web viewer; both listen on 127.0.0.1 only (rerun's default is 0.0.0.0).

The rerun SDK (a second to import) is loaded by :func:`save_rrd` alone, which imports
:mod:`~drill_twin.viz.rerun_native` when called: the twin asks this module for a display and a
viewer binary before it starts, and the replay for a log's stations.
"""
from __future__ import annotations

import os
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
from typing import Sequence

from drill_twin.viz.rerun_entities import APPLICATION_ID
from drill_twin.viz.run_columns import log_files
from drill_twin.viz.run_columns import stations_from_topics  # noqa: F401 (ros.replay's)

try:
    import rerun_cli                  # the viewer binary shipped with the rerun-sdk wheel
except ImportError:
    rerun_cli = None

LOCALHOST = '127.0.0.1'
DEFAULT_GRPC_PORT = 9876
DEFAULT_WEB_PORT = 9090
NO_DISPLAY_HINT = ('no display (DISPLAY and WAYLAND_DISPLAY are unset): write a file with '
                   '--rrd OUT.rrd, or serve the web viewer on localhost with --web')
LIVE_NO_DISPLAY_HINT = ('--view: no display (DISPLAY and WAYLAND_DISPLAY are unset): add '
                        "--web to serve rerun's web viewer on localhost, or look at the log "
                        'afterwards with `drill-twin view LOG --rrd OUT.rrd`')
"""What ``drill-twin twin --view`` says without a display."""


def has_display(environ=None) -> bool:
    """Tell whether a native window can open (an X11 or Wayland display is set)."""
    environ = os.environ if environ is None else environ
    return bool(environ.get('DISPLAY') or environ.get('WAYLAND_DISPLAY')
                or environ.get('WAYLAND_SOCKET')) or sys.platform in ('darwin', 'win32')


def save_rrd(source, rrd_path: str | os.PathLike, stations_m: Sequence[float] | None = None,
             *, active_tab: int | str | None = None,
             application_id: str = APPLICATION_ID) -> Path:
    """
    Convert a twin log into a self-contained ``.rrd`` (data and layout); returns its path.

    :param source: a ``.mcap`` file (also one cut short), a bag directory, or a list.
    :param stations_m: station depths (m); default: those of the log's topics.
    :param active_tab: the tab shown first (index or name, see
        :data:`~drill_twin.viz.rerun_entities.TABS`; None: the bit's, or the ensemble's for an
        offline estimate).
    """
    from drill_twin.viz.rerun_native import write_rrd       # rerun: see the module docstring

    return write_rrd(source, rrd_path, stations_m, active_tab=active_tab,
                     application_id=application_id)


def rerun_executable() -> str:
    """
    Find the rerun viewer binary.

    The one the rerun-sdk wheel ships (``rerun_cli/rerun``; the ``bin/rerun`` script only runs
    it as a child, which outlives a terminated script), else next to this Python (a venv's
    ``bin/rerun``), else on PATH.
    """
    if rerun_cli is not None:
        binary = Path(rerun_cli.__file__).with_name('rerun')
        if binary.is_file() and os.access(binary, os.X_OK):
            return str(binary)
    beside = Path(sys.executable).with_name('rerun')
    if beside.is_file() and os.access(beside, os.X_OK):
        return str(beside)
    found = shutil.which('rerun')
    if found is None:
        raise FileNotFoundError('no rerun executable (pip install rerun-sdk)')
    return found


def viewer_command(rrd_path: str | os.PathLike | None, *, web: bool = False,
                   port: int = DEFAULT_GRPC_PORT, web_port: int = DEFAULT_WEB_PORT,
                   extra_args: Sequence[str] = ()) -> list[str]:
    """
    Return the rerun command line for a viewer bound to 127.0.0.1.

    Native: the viewer window, its gRPC server on ``port``.  Web: rerun's web viewer over
    HTTP on ``web_port`` and the gRPC proxy on ``port``.  Without ``rrd_path`` the viewer
    waits for a live stream (``--expect-data-soon``).
    """
    command = [rerun_executable(), '--bind', LOCALHOST, '--port', str(port)]
    if web:
        command += ['--web-viewer', '--web-viewer-port', str(web_port)]
    command += [str(rrd_path)] if rrd_path is not None else ['--expect-data-soon']
    return command + list(extra_args)


def web_url(port: int = DEFAULT_GRPC_PORT, web_port: int = DEFAULT_WEB_PORT) -> str:
    """Address of the web viewer connected to the gRPC proxy on ``port``."""
    return (f'http://{LOCALHOST}:{web_port}/?url=rerun%2Bhttp%3A%2F%2F{LOCALHOST}%3A{port}'
            '%2Fproxy')


def open_viewer(source, stations_m: Sequence[float] | None = None, *,
                active_tab: int | str | None = None,
                rrd_dir: str | os.PathLike | None = None,
                web: bool = False, port: int = DEFAULT_GRPC_PORT,
                web_port: int = DEFAULT_WEB_PORT,
                extra_args: Sequence[str] = ()) -> subprocess.Popen:
    """
    Convert a log (see :func:`save_rrd`) and start rerun on it, bound to 127.0.0.1.

    Writes ``<log stem>.rrd`` into ``rrd_dir`` (default: a new temporary directory, left
    for the viewer to read); ``web`` serves the web viewer instead of opening a window.
    Returns the viewer process; the caller may ``wait()`` for it.
    """
    files = log_files(source)
    directory = Path(rrd_dir) if rrd_dir is not None else Path(
        tempfile.mkdtemp(prefix='drill_twin_rerun_'))
    rrd_path = save_rrd(files, directory / (files[0].stem + '.rrd'), stations_m,
                        active_tab=active_tab)
    return subprocess.Popen(viewer_command(rrd_path, web=web, port=port, web_port=web_port,
                                           extra_args=extra_args))
