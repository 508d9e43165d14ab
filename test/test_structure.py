"""
Sizes a reader can hold in mind: modules at most 600 lines, functions at most 80.

No function is exempt (LONG_FUNCTIONS lists any that must be, with the reason: the compiled
step is written as parts that numba inlines into one); the node module is held to 400 lines,
since it is meant to be a thin layer of wiring.
"""
from __future__ import annotations

import ast

from conftest import REPO

PACKAGE = REPO / 'drill_twin'
MAX_MODULE_LINES = 600
MAX_NODE_MODULE_LINES = 400
MAX_FUNCTION_LINES = 80
# Functions allowed beyond MAX_FUNCTION_LINES, by module, each with its reason. None at
# present: the compiled Newmark step (integrator/newmark_kernel.py) and its iteration's update
# (integrator/newmark_update.py) are written as parts that numba compiles into them
# (numerics.compiled.inline): an iteration's update is still one compiled function.
LONG_FUNCTIONS: dict[str, set[str]] = {}


def _modules():
    return sorted(PACKAGE.rglob('*.py'))


def test_no_module_is_longer_than_600_lines():
    long = {str(p.relative_to(REPO)): n for p in _modules()
            if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not long, long


def test_the_node_module_is_a_thin_layer():
    lines = len((PACKAGE / 'ros' / 'twin_node.py').read_text().splitlines())
    assert lines <= MAX_NODE_MODULE_LINES, lines


def test_no_function_is_longer_than_80_lines():
    long = {}
    for path in _modules():
        name = str(path.relative_to(REPO))
        for node in ast.walk(ast.parse(path.read_text(), name)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > MAX_FUNCTION_LINES and node.name not in LONG_FUNCTIONS.get(name, ()):
                    long[f'{name}:{node.lineno} {node.name}'] = length
    assert not long, long
