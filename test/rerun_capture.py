"""
Helpers of the tests of the rerun views.

A stand-in recording, the rerun CLI's environment (a fixture) and the entities and columns of
an ``.rrd``.
"""
from __future__ import annotations

import os
from pathlib import Path
import re
import subprocess

import numpy as np
import pytest

from drill_twin.viz.rerun_entities import TIMELINE
from drill_twin.viz.rerun_view import rerun_executable

CHUNK_LINE = re.compile(r'^Chunk\(\S+\) with \d+ rows \([^)]*\) - (\S+) - data columns: \[(.*)\]$')


@pytest.fixture(scope='module')
def rerun_env(tmp_path_factory):
    """Environment for the rerun CLI and SDK: analytics config kept out of $HOME."""
    root = tmp_path_factory.mktemp('rerun_home')
    overrides = {'XDG_CONFIG_HOME': str(root / 'config'), 'XDG_DATA_HOME': str(root / 'data'),
                 'RMW_IMPLEMENTATION': 'rmw_fastrtps_cpp'}
    saved = {key: os.environ.get(key) for key in overrides}
    os.environ.update(overrides)
    yield dict(os.environ)
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


def rrd_chunks(rrd: Path, env: dict) -> dict[str, set[str]]:
    """{entity path: data columns} of an .rrd, via ``rerun rrd print``."""
    result = subprocess.run([rerun_executable(), 'rrd', 'print', str(rrd)], env=env,
                            capture_output=True, text=True, check=True, timeout=60)
    columns: dict[str, set[str]] = {}
    for match in map(CHUNK_LINE.match, result.stdout.splitlines()):
        if match:
            columns.setdefault(match.group(1), set()).update(match.group(2).split())
    return columns


class Capture:
    """A stand-in recording: keeps what the layout functions send, as plain numbers."""

    def __init__(self):
        self.sent: dict[str, list] = {}
        self.static: dict[str, list] = {}

    def send_columns(self, entity, indexes, columns):
        (index,) = indexes
        assert index.timeline_name() == TIMELINE
        times = np.asarray(index.as_arrow_array().cast('int64').to_pylist()) * 1e-9
        values = {c.component_descriptor().component: c.as_arrow_array().to_pylist()
                  for c in columns}
        self.sent.setdefault(entity, []).append((times, values))

    def log(self, entity, archetype, static=False):
        assert static
        self.static.setdefault(entity, []).append(archetype)

    def flush(self):
        pass

    def rows(self, entity, component='Scalars:scalars'):
        """Return (times, values) of an entity over all its sends."""
        times = np.concatenate([t for t, _ in self.sent[entity]])
        values = [v for _, batch in self.sent[entity] for v in batch[component]]
        return times, values
