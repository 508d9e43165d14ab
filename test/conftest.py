"""Shared fixtures: the default configuration and model, and configuration builders."""
from __future__ import annotations

import contextlib
import copy
import fcntl
import functools
import os
import random
import sys
import tempfile
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from drill_twin.config.loader import _read_yaml, build_config, merge  # noqa: E402
from drill_twin.config.paths import default_config_path  # noqa: E402

REPO = Path(__file__).resolve().parents[1]

# Rerun writes analytics ids under the user's config directory: keep tests out of $HOME.
os.environ.setdefault('RERUN_TELEMETRY', '0')


def pytest_collection_modifyitems(config, items):
    """Mark every test under test/ros with ``ros`` (``-m 'not ros'`` runs the core alone)."""
    ros = Path(__file__).parent / 'ros'
    for item in items:
        if ros in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.ros)


DOMAIN_IDS = range(1, 101)
"""ROS domain ids the tests may use: those whose DDS ports lie below Linux's ephemeral ports
(domain 0, the default, is left to the user's own ROS programs)."""
DOMAIN_PURPOSES = ('nodes', 'processes', 'replay', 'command line')
"""What each id of a process's block is for: the twin and probe nodes in the test process,
twins run as processes, replayed logs, ``drill-twin twin`` start-up. Tests of one process run
one after another; each kind still gets an id of its own, so that what one leaves in the
middleware (a transient-local /rosout, a process still stopping) is heard by no other."""
DOMAIN_LOCKS = Path(tempfile.gettempdir()) / 'drill_twin_ros_domains'
"""Folder of the lock files by which pytest processes claim blocks of domain ids."""


def claim_domain_block(size: int = len(DOMAIN_PURPOSES), ids: range = DOMAIN_IDS,
                       folder: Path = DOMAIN_LOCKS):
    """
    Claim ``size`` consecutive ROS domain ids of ``ids`` that no other process holds.

    Each block of ``ids`` has a lock file in ``folder``; the claim is an exclusive ``flock``
    on it, held while the returned file stays open (for the process's life: the system lets
    it go when the process ends, however it ends). Two pytest sessions, or two pytest-xdist
    workers, thus never share a domain: a node in one would hear the other's twin. Blocks are
    tried from a random one on. Return (the ids, the open lock file); raise RuntimeError if
    every block is held.
    """
    folder.mkdir(parents=True, exist_ok=True)
    with contextlib.suppress(OSError):          # another user's sessions lock here too
        folder.chmod(0o1777)
    blocks = [ids[k:k + size] for k in range(0, len(ids) - size + 1, size)]
    first = random.SystemRandom().randrange(len(blocks))
    for block in blocks[first:] + blocks[:first]:
        path = folder / f'domains_{block[0]}-{block[-1]}.lock'
        try:
            descriptor = os.open(path, os.O_RDONLY | os.O_CREAT, 0o644)
        except OSError:
            continue
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:                         # held by another process
            os.close(descriptor)
            continue
        return list(block), os.fdopen(descriptor)
    raise RuntimeError(f'every block of {size} ROS domain ids in {ids.start}-{ids.stop - 1} '
                       f'is claimed by another process (lock files in {folder})')


@functools.cache
def _session_domains():
    """(ids, lock file) of this process, claimed once and held until it ends."""
    return claim_domain_block()


def session_domain_id(purpose: str) -> int:
    """Return the ROS domain id of this pytest process for ``purpose`` (DOMAIN_PURPOSES)."""
    return _session_domains()[0][DOMAIN_PURPOSES.index(purpose)]


def ros_variables(folder: Path, domain_id: int) -> dict[str, str]:
    """
    Environment of an isolated ROS 2 run.

    Its own domain, localhost only, FastDDS, the ROS logs and rerun's ids under ``folder``.
    """
    return {'ROS_DOMAIN_ID': str(domain_id), 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST',
            'RMW_IMPLEMENTATION': 'rmw_fastrtps_cpp', 'RERUN_TELEMETRY': '0',
            'ROS_LOG_DIR': str(folder / 'log'), 'XDG_CONFIG_HOME': str(folder / 'config'),
            'XDG_DATA_HOME': str(folder / 'data')}


@contextlib.contextmanager
def ros_environment(folder: Path, domain_id: int):
    """Run this process in :func:`ros_variables`; the environment is restored afterwards."""
    values = ros_variables(folder, domain_id)
    saved = {key: os.environ.get(key) for key in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def default_raw() -> dict:
    """Return the built-in defaults as a plain mapping (a fresh copy)."""
    return copy.deepcopy(_read_yaml(default_config_path()))


def config_with(changes: dict):
    """Return the defaults with ``changes`` merged in (lists replaced whole)."""
    return build_config(merge(default_raw(), changes), source='<test>')


def coarse_string(elements=(14, 4), lateral_modes=8, torsional_modes=4, axial_modes=3):
    """
    Return (config, reduced system) of the paper's string on a coarse mesh with a few modes.

    ``elements``: of the pipe and of the collars.
    """
    from drill_twin.model.reduced_system import build_reduced_system
    from drill_twin.modal.reduced_basis import modal_analysis
    sections = [dict(s, elements=n) for s, n in zip(default_raw()['sections'], elements)]
    config = config_with({'sections': sections,
                          'reduced_basis': {'lateral_modes': lateral_modes,
                                            'torsional_modes': torsional_modes,
                                            'axial_modes': axial_modes}})
    model, _, basis = modal_analysis(config)
    return config, build_reduced_system(model, basis)


def physics_off() -> dict:
    """Every physical effect switched off."""
    return {name: False for name in default_raw()['physics']}


@pytest.fixture(scope='session')
def default_config():
    from drill_twin.config import load_config
    return load_config()


@pytest.fixture(scope='session')
def default_analysis(default_config):
    """(model, modes, basis) of the default configuration."""
    from drill_twin.modal.reduced_basis import modal_analysis
    return modal_analysis(default_config)
