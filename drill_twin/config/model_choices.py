"""
The model's switches and readings.

Which effects are on, the damping, the reduced basis, and the readings of the paper tested for
its lateral response (docs/MODEL-CHOICES.md).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from drill_twin.config.bounds import (
    MASS_DAMPING_MAX_PER_S, MASS_DAMPING_REASON, STIFFNESS_DAMPING_MAX_S,
    STIFFNESS_DAMPING_REASON)
from drill_twin.config.checks import at_most, ConfigValueError, non_negative

KineticCouplingSign = Literal['derived', 'printed']
StrainKinematics = Literal['invariant', 'printed_elastic', 'printed_absolute']
StiffnessDamping = Literal['fixed_frame', 'rotating_frame']


@dataclass(frozen=True, slots=True, kw_only=True)
class Physics:
    """Switches for every physical effect, so that analytic limits can be run."""

    gravity: bool
    prestress: bool
    fluid: bool
    stabilizers: bool
    contact: bool
    bit_rock: bool
    kinetic_coupling: bool
    finite_strain: bool


@dataclass(frozen=True, slots=True, kw_only=True)
class Damping:
    """Rayleigh damping [C] = alpha ([M] + [M_f]) + beta ([K] + [K_f] + [K_g])."""

    mass_coefficient_per_s: float
    stiffness_coefficient_s: float

    def __post_init__(self):
        non_negative(self, 'mass_coefficient_per_s', 'stiffness_coefficient_s')
        at_most(self, 'mass_coefficient_per_s', MASS_DAMPING_MAX_PER_S, MASS_DAMPING_REASON)
        at_most(self, 'stiffness_coefficient_s', STIFFNESS_DAMPING_MAX_S,
                STIFFNESS_DAMPING_REASON)


@dataclass(frozen=True, slots=True, kw_only=True)
class ReducedBasis:
    """How many normal modes of each type the reduced model keeps (rigid modes are added)."""

    lateral_modes: int
    torsional_modes: int
    axial_modes: int

    def __post_init__(self):
        for name in ('lateral_modes', 'torsional_modes', 'axial_modes'):
            if getattr(self, name) < 0:
                raise ConfigValueError(name, f'must be >= 0, got {getattr(self, name)}')


@dataclass(frozen=True, slots=True, kw_only=True)
class LateralReadings:
    """
    Readings of the paper selectable for its lateral response (docs/LATERAL.md).

    The defaults are the readings taken (docs/MODEL-CHOICES.md, docs/LATERAL.md).

    kinetic_coupling: 'derived' (T_c = -rho I_p theta_x' theta_y theta_z', the sign that
    follows from the rotation sequence) or 'printed' (Eq. 8-11 as printed: the opposite).
    strain_kinematics: Eq. 15 'invariant' (the section twisted, then tilted: the energy does
    not depend on the spin angle) or as printed (u_x = u - y theta_z + z theta_y), with
    theta_x the elastic twist ('printed_elastic') or the absolute angle, top drive's included
    ('printed_absolute'); docs/LATERAL.md, "Eq. 15 as printed".
    stiffness_damping: Rayleigh's beta K_t acting on the velocities in the fixed frame
    ('fixed_frame', the paper's [C] u') or on the strain rates of the spinning string
    ('rotating_frame': internal damping, which adds the circulatory force of
    model/rotating_damping.py); docs/LATERAL.md, "What feeds the lateral modes".
    """

    kinetic_coupling: KineticCouplingSign = 'derived'
    strain_kinematics: StrainKinematics = 'invariant'
    stiffness_damping: StiffnessDamping = 'fixed_frame'
