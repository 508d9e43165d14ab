"""The documents agree with the code they describe."""
from __future__ import annotations

import yaml
from conftest import REPO

from drill_twin.ros.parameters import PARAMETERS, markdown_table


def test_parameter_table_matches_the_declared_parameters():
    text = (REPO / 'docs' / 'ROS-INTERFACE.md').read_text()
    assert markdown_table() in text, 'regenerate the table with parameters.markdown_table()'


def test_shipped_twin_parameters_are_declared_with_the_same_defaults():
    shipped = yaml.safe_load((REPO / 'config' / 'twin.yaml').read_text())
    values = shipped['drill_twin']['ros__parameters']
    declared = {p.name: p.default for p in PARAMETERS}
    assert set(values) <= set(declared), set(values) - set(declared)
    for name, value in values.items():
        assert value == declared[name], (name, value, declared[name])
