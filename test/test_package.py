"""The package installs as an ament_python package and keeps its core free of ROS."""
from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from conftest import REPO


def test_package_xml():
    root = ET.parse(REPO / 'package.xml').getroot()
    assert root.get('format') == '3'
    assert root.findtext('name') == 'drill_twin'
    assert root.find('export/build_type').text == 'ament_python'
    depends = {e.text for e in root.findall('exec_depend')}
    assert {'rclpy', 'std_msgs', 'sensor_msgs', 'geometry_msgs', 'diagnostic_msgs'} <= depends


def test_layout():
    for path in ('setup.py', 'setup.cfg', 'resource/drill_twin', 'config/ritto2009.yaml',
                 'drill_twin/__init__.py', 'scripts/twin'):
        assert (REPO / path).exists(), path
    assert os.access(REPO / 'scripts/twin', os.X_OK)


@pytest.fixture(scope='module')
def installed_prefix(tmp_path_factory):
    """Install the package for real (non-editable) with pip into a fresh prefix."""
    prefix = tmp_path_factory.mktemp('prefix')
    before = _installed_location()
    # --ignore-installed: without it pip first uninstalls the copy in the running
    # environment (the developer's editable install).
    subprocess.run([sys.executable, '-m', 'pip', 'install', '--quiet', '--no-deps',
                    '--ignore-installed', '--no-build-isolation', '--disable-pip-version-check',
                    '--prefix', str(prefix), str(REPO)], check=True, capture_output=True,
                   timeout=300)
    assert _installed_location() == before, 'installing into a prefix disturbed the venv'
    return prefix


def _installed_location():
    result = subprocess.run([sys.executable, '-c',
                             'import drill_twin; print(drill_twin.__file__)'],
                            capture_output=True, text=True, cwd='/', timeout=60)
    return result.stdout.strip()


def test_install_puts_the_ament_files_in_place(installed_prefix):
    share = installed_prefix / 'share'
    assert (share / 'ament_index/resource_index/packages/drill_twin').is_file()
    assert (share / 'drill_twin/package.xml').is_file()
    assert (share / 'drill_twin/config/ritto2009.yaml').is_file()
    launcher = installed_prefix / 'lib/drill_twin/twin'
    assert launcher.is_file() and os.access(launcher, os.X_OK)
    assert (installed_prefix / 'bin/drill-twin').is_file()


def test_installed_command_finds_its_configuration(installed_prefix):
    """The installed copy (not the source tree) must find share/drill_twin/config."""
    purelib = sysconfig.get_path('purelib', vars={'base': str(installed_prefix),
                                                  'platbase': str(installed_prefix)})
    env = dict(os.environ, PYTHONPATH=purelib)
    result = subprocess.run([sys.executable, str(installed_prefix / 'bin/drill-twin'), 'modes',
                             '--count', '1', '--json'], capture_output=True, text=True,
                            env=env, cwd=installed_prefix, timeout=120)
    assert result.returncode == 0, result.stderr
    probe = subprocess.run([sys.executable, '-c',
                            'import drill_twin.config.paths as p; print(p.default_config_path())'],
                           capture_output=True, text=True, env=env, cwd=installed_prefix)
    assert probe.stdout.strip().startswith(str(installed_prefix / 'share/drill_twin/config'))


def test_core_never_imports_rclpy():
    code = ('import sys\n'
            'import drill_twin.config, drill_twin.fem.model, drill_twin.modal.reduced_basis\n'
            'import drill_twin.cli.main, drill_twin.interface\n'
            'assert "rclpy" not in sys.modules, "the core imported rclpy"\n')
    subprocess.run([sys.executable, '-c', code], check=True, timeout=60)


def test_console_command_lists_subcommands():
    result = subprocess.run([sys.executable, '-m', 'drill_twin.cli.main', '--help'],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0
    assert 'modes' in result.stdout


def test_package_xml_declares_what_the_node_imports():
    root = ET.parse(REPO / 'package.xml').getroot()
    depends = {e.text for e in root.findall('exec_depend')}
    assert {'python3-numpy', 'python3-scipy', 'python3-yaml', 'python3-numba', 'launch',
            'launch_ros', 'ament_index_python'} <= depends


def test_launch_file_is_installed_and_starts_the_twin(installed_prefix, monkeypatch):
    """
    ``ros2 launch drill_twin twin.launch.py``.

    The launch file is installed, and its description starts the ``twin`` executable of this
    package with the installed parameters.

    launch and launch_ros are not on PyPI, so they are replaced by recorders of what the file
    asks for (the only part mocked); the file itself and the paths are the installed ones.
    """
    import types

    path = installed_prefix / 'share/drill_twin/launch/twin.launch.py'
    assert path.is_file()
    recorded = {}

    def record(kind):
        def make(*args, **kwargs):
            recorded.setdefault(kind, []).append((args, kwargs))
            return (kind, args, kwargs)
        return make

    stubs = {
        'launch': types.SimpleNamespace(LaunchDescription=record('description')),
        'launch.actions': types.SimpleNamespace(DeclareLaunchArgument=record('argument')),
        'launch.substitutions': types.SimpleNamespace(LaunchConfiguration=lambda name: name),
        'launch_ros.actions': types.SimpleNamespace(Node=record('node')),
        'ament_index_python.packages': types.SimpleNamespace(
            get_package_share_directory=lambda name: str(installed_prefix / 'share' / name)),
    }
    for name, module in stubs.items():
        monkeypatch.setitem(sys.modules, name, module)
    namespace = {}
    exec(compile(path.read_text(), str(path), 'exec'), namespace)
    namespace['generate_launch_description']()
    (_, node), = recorded['node']
    assert node['package'] == 'drill_twin' and node['executable'] == 'twin'
    assert (installed_prefix / 'lib/drill_twin' / node['executable']).is_file()
    defaults = {args[0]: kwargs.get('default_value') for args, kwargs in recorded['argument']}
    assert set(defaults) >= {'params_file', 'use_sim_time', 'model_config', 'log_dir'}
    params_file = defaults['params_file']
    assert params_file == str(installed_prefix / 'share/drill_twin/config/twin.yaml')
    import yaml
    assert 'ros__parameters' in yaml.safe_load(open(params_file))[node['name']]


def test_an_editable_install_is_an_ament_prefix(tmp_path):
    """
    ``make setup``'s editable install, made an ament prefix by scripts/link_ament_files.py.

    In a fresh prefix: ament_index finds the package's share directory, its files are the
    source tree's, and the ``ros2 run`` launcher runs with this Python.
    """
    prefix = tmp_path / 'prefix'
    (prefix / 'bin').mkdir(parents=True)
    (prefix / 'bin' / 'python').symlink_to(sys.executable)
    (prefix / 'bin' / 'activate').write_text('VIRTUAL_ENV=somewhere\n')
    subprocess.run([sys.executable, str(REPO / 'scripts/link_ament_files.py'), str(prefix),
                    '--activate'], check=True, capture_output=True, timeout=60)
    code = ('from ament_index_python.packages import get_package_share_directory as share\n'
            'print(share("drill_twin"))\n')
    found = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                           env=dict(os.environ, AMENT_PREFIX_PATH=str(prefix)), timeout=60)
    assert found.stdout.strip() == str(prefix / 'share' / 'drill_twin'), found.stderr
    share = prefix / 'share' / 'drill_twin'
    for name in ('package.xml', 'config/twin.yaml', 'config/ritto2009.yaml',
                 'launch/twin.launch.py'):
        assert (share / name).resolve() == (REPO / name).resolve(), name
    assert (prefix / 'share/ament_index/resource_index/packages/drill_twin').exists()
    launcher = prefix / 'lib' / 'drill_twin' / 'twin'
    assert os.access(launcher, os.X_OK)
    assert launcher.read_text().splitlines()[0] == f'#!{prefix.resolve()}/bin/python'
    usage = subprocess.run([sys.executable, str(launcher), '--help'], capture_output=True,
                           text=True, timeout=120)
    assert usage.returncode == 0 and usage.stdout.startswith('usage: drill-twin twin')
    activate = (prefix / 'bin' / 'activate').read_text()
    assert activate.count('export AMENT_PREFIX_PATH="$VIRTUAL_ENV') == 1


def test_the_environment_of_make_setup_is_an_ament_prefix():
    """The venv the tests run in (made by ``make setup``) holds the ament files."""
    if not (Path(sys.prefix) / 'bin' / 'activate').is_file():
        pytest.skip('not running in a virtual environment')
    share = Path(sys.prefix) / 'share' / 'drill_twin'
    assert (share / 'package.xml').exists(), 'run make setup (scripts/link_ament_files.py)'
    assert (Path(sys.prefix) / 'lib' / 'drill_twin' / 'twin').exists()
