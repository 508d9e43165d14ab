"""Where the shipped configuration files are, in a source tree or an installed package."""
from __future__ import annotations

import os
import sys
from pathlib import Path

DEFAULT_CONFIG_NAME = 'ritto2009.yaml'


def config_directory() -> Path:
    """
    Return the directory holding the shipped ``*.yaml`` files.

    Looked up in order: ``$DRILL_TWIN_CONFIG_DIR``; the source tree (``config/`` beside
    the package, for editable installs); ``share/drill_twin/config`` under the
    installation prefix (pip or colcon).
    """
    candidates = []
    if os.environ.get('DRILL_TWIN_CONFIG_DIR'):
        candidates.append(Path(os.environ['DRILL_TWIN_CONFIG_DIR']))
    package_dir = Path(__file__).resolve().parents[1]
    candidates.append(package_dir.parent / 'config')
    # <prefix>/lib/pythonX.Y/site-packages/drill_twin -> <prefix>/share/drill_twin/config
    if len(package_dir.parents) > 3:
        candidates.append(package_dir.parents[3] / 'share' / 'drill_twin' / 'config')
    candidates.append(Path(sys.prefix) / 'share' / 'drill_twin' / 'config')
    for directory in candidates:
        if (directory / DEFAULT_CONFIG_NAME).is_file():
            return directory
    raise FileNotFoundError(
        'drill_twin: cannot find the shipped configuration (config/ritto2009.yaml); '
        'looked in ' + ', '.join(str(c) for c in candidates))


def default_config_path() -> Path:
    """Path of the built-in defaults, ``ritto2009.yaml``."""
    return config_directory() / DEFAULT_CONFIG_NAME
