"""
The architecture as written in setup.cfg's ``[importlinter]`` contracts, checked by import-linter.

The layers (cli > ros > viz > recording > twin > assimilation > uncertainty > simulation >
analysis > rig > integrator > model > modal > fem > numerics > config | interface) and the
ROS-free core are declared once, in setup.cfg; ``lint-imports`` reads every import, including
those inside functions, so no deferred import can hide a cycle.
"""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

from conftest import REPO
import grimp


def _lint_imports() -> subprocess.CompletedProcess:
    executable = Path(sys.executable).with_name('lint-imports')
    env = dict(os.environ, PYTHONPATH=str(REPO))
    return subprocess.run([str(executable), '--no-cache'], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=300)


def test_the_import_contracts_of_setup_cfg_are_kept():
    run = _lint_imports()
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-2000:]
    assert 'Contracts: 2 kept, 0 broken.' in run.stdout, run.stdout[-2000:]


def test_importing_the_core_leaves_rclpy_out():
    """Every package below ``ros`` imported in a fresh interpreter: no rclpy, no rerun."""
    core = ('config', 'interface', 'numerics', 'fem', 'modal', 'model', 'integrator', 'rig',
            'analysis', 'simulation', 'uncertainty', 'assimilation', 'twin')
    code = ('import importlib, pkgutil, sys\n'
            'import drill_twin\n'
            f'for name in {core!r}:\n'
            '    package = importlib.import_module("drill_twin." + name)\n'
            '    for info in pkgutil.iter_modules(getattr(package, "__path__", [])):\n'
            '        if info.name != "ensemble_worker":\n'
            '            importlib.import_module(f"drill_twin.{name}.{info.name}")\n'
            'print(sorted(m for m in sys.modules if m.split(".")[0] in ("rclpy", "rerun")))\n')
    run = subprocess.run([sys.executable, '-c', code], cwd=REPO, capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    assert run.stdout.strip() == '[]'


def test_no_module_imports_itself_through_others():
    """
    No cycle between modules either, inside a package included (grimp, import-linter's graph).

    For every import a -> b, no chain of imports leads from b back to a.
    """
    graph = grimp.build_graph('drill_twin', cache_dir=None)
    cycles = []
    for module in sorted(graph.modules):
        for imported in sorted(graph.find_modules_directly_imported_by(module)):
            back = graph.find_shortest_chain(importer=imported, imported=module)
            if back:
                cycles.append(' -> '.join((module, *back)))
    assert not cycles, cycles
