"""The borehole, with the string's contact law on its wall, and the drilling mud."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from drill_twin.config.bounds import (
    DRAG_COEFFICIENT_MAX, DRAG_REASON, FRICTION_COEFFICIENT_MAX, FRICTION_REASON,
    HOLE_DIAMETER_MAX_M, HOLE_DIAMETER_REASON, MUD_DENSITY_MAX_KG_PER_M3, MUD_DENSITY_REASON,
    MUD_SPEED_MAX_M_PER_S, MUD_SPEED_REASON, SPRING_STIFFNESS_MAX_N_PER_M,
    SPRING_STIFFNESS_REASON)
from drill_twin.config.checks import at_most, non_negative, positive

CoriolisForm = Literal['gyroscopic', 'paper']


@dataclass(frozen=True, slots=True, kw_only=True)
class Borehole:
    """
    The hole and the impact/rubbing law between string and wall (Eq. 17-18).

    tangential_friction: the wall's friction as a force at the contact point (it can drive
    backward whirl) instead of the paper's rubbing torque alone (model/contact.py).
    """

    diameter_m: float
    contact_stiffness_n_per_m: float
    friction_coefficient: float
    friction_regularization_rad_per_s: float
    tangential_friction: bool = False

    def __post_init__(self):
        positive(self, 'diameter_m', 'contact_stiffness_n_per_m',
                 'friction_regularization_rad_per_s')
        non_negative(self, 'friction_coefficient')
        at_most(self, 'diameter_m', HOLE_DIAMETER_MAX_M, HOLE_DIAMETER_REASON)
        at_most(self, 'contact_stiffness_n_per_m', SPRING_STIFFNESS_MAX_N_PER_M,
                SPRING_STIFFNESS_REASON)
        at_most(self, 'friction_coefficient', FRICTION_COEFFICIENT_MAX, FRICTION_REASON)


@dataclass(frozen=True, slots=True, kw_only=True)
class Fluid:
    """Drilling mud inside the string and in the annulus (Eq. 19-23)."""

    density_kg_per_m3: float
    inlet_speed_m_per_s: float
    drag_coefficient: float
    viscous_damping_n_s_per_m2: float
    coriolis: CoriolisForm

    def __post_init__(self):
        positive(self, 'density_kg_per_m3')
        non_negative(self, 'inlet_speed_m_per_s', 'drag_coefficient',
                     'viscous_damping_n_s_per_m2')
        at_most(self, 'density_kg_per_m3', MUD_DENSITY_MAX_KG_PER_M3, MUD_DENSITY_REASON)
        at_most(self, 'inlet_speed_m_per_s', MUD_SPEED_MAX_M_PER_S, MUD_SPEED_REASON)
        at_most(self, 'drag_coefficient', DRAG_COEFFICIENT_MAX, DRAG_REASON)
