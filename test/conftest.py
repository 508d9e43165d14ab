"""Shared fixtures: the default configuration and model, and configuration builders."""
from __future__ import annotations

import contextlib
import copy
import os
import sys
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


def worker_domain_ids(low: int, high: int) -> range:
    """
    Return the ROS domain ids of ``range(low, high)`` this pytest process may use.

    pytest-xdist runs test files side by side in worker processes (``make test``): worker k of
    n takes every n-th id from low + k, so two workers never share a domain (a node in one
    would hear the other's twin). Without xdist, the whole range.
    """
    worker = os.environ.get('PYTEST_XDIST_WORKER', 'gw0')
    count = int(os.environ.get('PYTEST_XDIST_WORKER_COUNT', '1'))
    return range(low + int(worker.removeprefix('gw')), high, count)


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
