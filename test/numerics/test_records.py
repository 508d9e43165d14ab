"""Frozen dataclass instances made at the time loop's rate (drill_twin.numerics.records)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from drill_twin.integrator.batch_state import StepResult, make_step_result
from drill_twin.model.contact import ContactForces
from drill_twin.numerics.records import record

FIELDS = dict(success=True, converged=np.ones(2, dtype=bool), finite=np.ones(2, dtype=bool),
              iterations=2, error=np.zeros(2), message='', forces=None,
              retries=np.zeros(2, dtype=int), on_bottom=np.ones(2, dtype=bool),
              members_on_bottom=2, members_lifted=0)


def test_a_record_is_the_classs_own_and_stays_frozen():
    made, built = record(StepResult, **FIELDS), StepResult(**FIELDS)
    assert type(made) is StepResult
    assert vars(made).keys() == vars(built).keys()
    for name, value in vars(built).items():
        assert getattr(made, name) is value
    with pytest.raises(dataclasses.FrozenInstanceError):
        made.success = False
    assert dataclasses.replace(made, message='x').message == 'x'
    positional = make_step_result(*FIELDS.values())
    assert all(getattr(positional, name) is value for name, value in FIELDS.items())


def test_every_field_is_given_by_name():
    contact = record(ContactForces, radial_force_n=np.zeros(3), in_contact=np.zeros(3, bool))
    assert contact.radial_force_n.shape == (3,) and not contact.in_contact.any()
    with pytest.raises(TypeError, match='missing'):
        record(ContactForces, radial_force_n=np.zeros(3))
    with pytest.raises(TypeError, match='unknown'):
        record(ContactForces, radial_force_n=np.zeros(3), in_contact=np.zeros(3, bool),
               tangent=None)
    with pytest.raises(TypeError):
        record(ContactForces, np.zeros(3), np.zeros(3, bool))          # not by position


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
            record(cls, x=1.0)
