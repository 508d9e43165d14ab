"""The package's import graph: no cycles between modules, the core free of ROS and plotting.

Imports are read from the source (``ast``), at module level and inside functions alike, so a
cycle hidden in a deferred import counts too.
"""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / 'drill_twin'


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix('').parts
    return '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)


def import_graph() -> dict[str, set[str]]:
    """Map every module of the package to the drill_twin modules it imports."""
    modules = {_module_name(p): p for p in PACKAGE.rglob('*.py')}
    graph = {}
    for name, path in modules.items():
        targets = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                candidates = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                candidates = [node.module] + [f'{node.module}.{a.name}' for a in node.names]
            else:
                continue
            targets.update(c for c in candidates if c in modules and c != name)
        graph[name] = targets
    return graph


def _cycle_through(graph, start: str) -> list[str] | None:
    """Find a path start -> ... -> start, if there is one."""
    stack, seen = [(start, [start])], set()
    while stack:
        node, path = stack.pop()
        for target in graph.get(node, ()):
            if target == start:
                return path + [start]
            if target not in seen and not target.endswith('__init__'):
                seen.add(target)
                stack.append((target, path + [target]))
    return None


def test_study_io_and_plotting_do_not_import_each_other_in_a_cycle():
    graph = import_graph()
    packages = ('drill_twin.uncertainty', 'drill_twin.plotting')
    for start in [m for m in graph if m.startswith(packages)]:
        cycle = _cycle_through(graph, start)
        assert cycle is None, ' -> '.join(cycle)


def test_the_numerical_core_imports_neither_ros_nor_the_thin_layers():
    core = ('config', 'fem', 'modal', 'dynamics', 'simulation', 'uncertainty', 'twin')
    layers = ('drill_twin.ros', 'drill_twin.recording', 'drill_twin.cli')
    offenders = []
    for path in PACKAGE.rglob('*.py'):
        name = _module_name(path)
        if name.split('.')[1:2] and name.split('.')[1] in core:
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                modules = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                           [node.module or ''] if isinstance(node, ast.ImportFrom) else [])
                offenders += [f'{name} imports {m}' for m in modules
                              if m.split('.')[0] == 'rclpy' or m.startswith(layers)]
    assert not offenders, offenders
