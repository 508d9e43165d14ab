"""
The string's build: sections of tubulars, stabilizers, the lumped bit and the end conditions.

x is the string axis pointing down from the top (x = 0) to the bit (docs/MODEL-CHOICES.md).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from drill_twin.config.bounds import (
    BIT_INERTIA_MAX_KG_M2, BIT_INERTIA_REASON, BIT_MASS_MAX_KG, BIT_MASS_REASON, ELEMENTS_MAX,
    ELEMENTS_REASON, HOLE_DIAMETER_MAX_M, HOLE_DIAMETER_REASON, LENGTH_MAX_M, LENGTH_REASON,
    SOLID_DENSITY_RANGE_KG_PER_M3, SOLID_DENSITY_REASON, SPRING_STIFFNESS_MAX_N_PER_M,
    SPRING_STIFFNESS_REASON, YOUNG_MODULUS_RANGE_PA, YOUNG_MODULUS_REASON)
from drill_twin.config.checks import at_least, at_most, ConfigValueError, non_negative, positive

SectionKind = Literal['drill_pipe', 'heavy_weight_pipe', 'drill_collar', 'other']
AxialEnd = Literal['free', 'fixed']
TorsionTop = Literal['driven', 'free']
TorsionBit = Literal['free', 'fixed']
LateralEnd = Literal['clamped', 'pinned', 'free']


@dataclass(frozen=True, slots=True, kw_only=True)
class Section:
    """
    A run of identical tubulars (drill pipe, heavy-weight pipe, collars).

    Sections are listed top to bottom; ``elements`` finite elements of equal length
    discretise the section.
    """

    name: str
    kind: SectionKind
    length_m: float
    outer_diameter_m: float
    inner_diameter_m: float
    elements: int
    young_modulus_pa: float
    density_kg_per_m3: float
    poisson_ratio: float
    shear_correction_factor: float

    def __post_init__(self):
        positive(self, 'length_m', 'outer_diameter_m', 'young_modulus_pa',
                 'density_kg_per_m3', 'shear_correction_factor')
        non_negative(self, 'inner_diameter_m')
        if self.inner_diameter_m >= self.outer_diameter_m:
            raise ConfigValueError(
                'inner_diameter_m',
                f'must be smaller than outer_diameter_m ({self.outer_diameter_m} m), '
                f'got {self.inner_diameter_m} m')
        if self.elements < 1:
            raise ConfigValueError('elements', f'must be at least 1, got {self.elements}')
        at_most(self, 'elements', ELEMENTS_MAX, ELEMENTS_REASON)
        at_most(self, 'length_m', LENGTH_MAX_M, LENGTH_REASON)
        at_most(self, 'outer_diameter_m', HOLE_DIAMETER_MAX_M, HOLE_DIAMETER_REASON)
        at_least(self, 'young_modulus_pa', YOUNG_MODULUS_RANGE_PA[0], YOUNG_MODULUS_REASON)
        at_most(self, 'young_modulus_pa', YOUNG_MODULUS_RANGE_PA[1], YOUNG_MODULUS_REASON)
        at_least(self, 'density_kg_per_m3', SOLID_DENSITY_RANGE_KG_PER_M3[0],
                 SOLID_DENSITY_REASON)
        at_most(self, 'density_kg_per_m3', SOLID_DENSITY_RANGE_KG_PER_M3[1],
                SOLID_DENSITY_REASON)
        if not -1.0 < self.poisson_ratio < 0.5:
            raise ConfigValueError('poisson_ratio',
                                   f'must lie in (-1, 0.5), got {self.poisson_ratio}')
        if self.shear_correction_factor > 1.0:
            raise ConfigValueError('shear_correction_factor',
                                   f'must lie in (0, 1], got {self.shear_correction_factor}')

    @property
    def shear_modulus_pa(self) -> float:
        """G = E / (2 (1 + nu)), Pa."""
        return self.young_modulus_pa / (2.0 * (1.0 + self.poisson_ratio))


@dataclass(frozen=True, slots=True, kw_only=True)
class Stabilizer:
    """A stabilizer modelled as lateral springs at one point (paper Eq. 28)."""

    name: str
    position_m: float
    stiffness_n_per_m: float

    def __post_init__(self):
        non_negative(self, 'position_m', 'stiffness_n_per_m')
        at_most(self, 'stiffness_n_per_m', SPRING_STIFFNESS_MAX_N_PER_M, SPRING_STIFFNESS_REASON)


@dataclass(frozen=True, slots=True, kw_only=True)
class Bit:
    """Lumped rigid bit (and motor) at the bottom node."""

    mass_kg: float
    polar_inertia_kg_m2: float

    def __post_init__(self):
        non_negative(self, 'mass_kg', 'polar_inertia_kg_m2')
        at_most(self, 'mass_kg', BIT_MASS_MAX_KG, BIT_MASS_REASON)
        at_most(self, 'polar_inertia_kg_m2', BIT_INERTIA_MAX_KG_M2, BIT_INERTIA_REASON)


@dataclass(frozen=True, slots=True, kw_only=True)
class Boundary:
    """End conditions. The top is held by the hook (axially free) and driven in rotation."""

    top_axial: AxialEnd
    top_torsion: TorsionTop
    top_lateral: LateralEnd
    bit_axial: AxialEnd
    bit_torsion: TorsionBit
    bit_lateral: LateralEnd
