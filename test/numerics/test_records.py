"""Frozen records made at the time loop's rate (drill_twin.numerics.records)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from drill_twin.model.contact import ContactForces
from drill_twin.integrator.newmark import StepResult, make_step_result
from drill_twin.numerics.records import maker


def test_a_made_record_is_the_classs_own_and_stays_frozen():
    values = (True, np.ones(2, dtype=bool), np.ones(2, dtype=bool), 2, np.zeros(2), '',
              None, np.zeros(2, dtype=int), np.ones(2, dtype=bool), 2, 0)
    made, built = make_step_result(*values), StepResult(*values)
    assert type(made) is StepResult
    assert vars(made).keys() == vars(built).keys()
    for name, value in vars(built).items():
        assert getattr(made, name) is value
    with pytest.raises(dataclasses.FrozenInstanceError):
        made.success = False
    assert dataclasses.replace(made, message='x').message == 'x'
    contact = maker(ContactForces)(radial_force_n=np.zeros(3), in_contact=np.zeros(3, bool))
    assert contact.radial_force_n.shape == (3,) and not contact.in_contact.any()
    with pytest.raises(TypeError):
        maker(ContactForces)(np.zeros(3))                  # every field is given


def test_only_plain_frozen_dataclasses_are_made_so():
    @dataclasses.dataclass
    class Mutable:
        x: float

    @dataclasses.dataclass(frozen=True)
    class Checked:
        x: float

        def __post_init__(self):
            assert self.x > 0

    for cls in (Mutable, Checked, dict):
        with pytest.raises(TypeError):
            maker(cls)
