"""
The configuration of a drill-string model as frozen dataclasses.

Every quantity is SI and carries its unit in its name. The checks refuse input that is
physically impossible; the loader (``loader.py``) turns YAML into these objects and prefixes
every error with the key path it came from.

:class:`DrillStringConfig` is the whole; its parts live by concept beside it, and every name
is importable from here:

- ``sections`` - the string's build (sections, stabilizers, the lumped bit, end conditions)
- ``hole`` - the borehole and its wall contact, the drilling mud
- ``bit_rock`` - the bit-rock law
- ``drives`` - the set point, the top drive and the drawworks
- ``model_choices`` - physics switches, damping, reduced basis, the paper's lateral readings
- ``integration`` - the Newmark step, the initial state, the output
- ``excitation`` - imbalance and a lobed hole bottom
- ``checks`` and ``bounds`` - the value checks, their error and the plausibility bounds

Conventions (see ``docs/MODEL-CHOICES.md``): x is the string axis pointing down from the
top (x = 0) to the bit; forces along x are positive downwards, so the weight on bit of the
paper (``f_bit``) is negative in compression.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from drill_twin.config.bit_rock import BitRock
from drill_twin.config.bounds import (
    ELEMENTS_MAX, ELEMENTS_REASON, GRAVITY_MAX_M_PER_S2, GRAVITY_REASON, LENGTH_MAX_M,
    LENGTH_REASON)
from drill_twin.config.checks import at_most, ConfigValueError, positive
from drill_twin.config.drives import (
    DrawworksMode, DriveController, Drawworks, Operation, TopDrive, TopDriveMode)
from drill_twin.config.excitation import BottomHolePattern, Excitation, Imbalance
from drill_twin.config.hole import Borehole, CoriolisForm, Fluid
from drill_twin.config.integration import InitialConditions, InitialShape, Integration, Output
from drill_twin.config.model_choices import (
    Damping, KineticCouplingSign, LateralReadings, Physics, ReducedBasis, StiffnessDamping,
    StrainKinematics)
from drill_twin.config.sections import (
    AxialEnd, Bit, Boundary, LateralEnd, Section, SectionKind, Stabilizer, TorsionBit,
    TorsionTop)

__all__ = [
    'AxialEnd', 'Bit', 'BitRock', 'Borehole', 'BottomHolePattern', 'Boundary',
    'ConfigValueError', 'CoriolisForm', 'Damping', 'Drawworks', 'DrawworksMode',
    'DriveController', 'DrillStringConfig', 'Excitation', 'Fluid', 'Imbalance',
    'InitialConditions', 'InitialShape', 'Integration', 'KineticCouplingSign', 'LateralEnd',
    'LateralReadings', 'Operation', 'Output', 'Physics', 'ReducedBasis', 'Section',
    'SectionKind', 'Stabilizer', 'StiffnessDamping', 'StrainKinematics', 'TopDrive',
    'TopDriveMode', 'TorsionBit', 'TorsionTop']


@dataclass(frozen=True, slots=True, kw_only=True)
class DrillStringConfig:
    """
    A whole vertical drill string, its hole, fluid, bit and the model choices.

    The parts check their own values; this class checks how they fit together.
    """

    sections: tuple[Section, ...]
    stabilizers: tuple[Stabilizer, ...]
    borehole: Borehole
    fluid: Fluid
    gravity_m_per_s2: float
    bit_rock: BitRock
    bit: Bit
    operation: Operation
    boundary: Boundary
    physics: Physics
    damping: Damping
    reduced_basis: ReducedBasis
    integration: Integration
    initial_conditions: InitialConditions
    output: Output
    top_drive: TopDrive = TopDrive()
    drawworks: Drawworks = Drawworks()
    excitation: Excitation = field(default_factory=Excitation)
    lateral_readings: LateralReadings = field(default_factory=LateralReadings)
    source: str = field(default='<defaults>', compare=False)
    """Where the configuration came from (for error messages and log metadata)."""

    def __post_init__(self):
        if not self.sections:
            raise ConfigValueError('sections', 'at least one section is needed')
        names = [s.name for s in self.sections]
        for index, name in enumerate(names):
            if names.index(name) != index:
                raise ConfigValueError(f'sections.{index}.name', f'duplicate name {name!r}')
        positive(self, 'gravity_m_per_s2')
        at_most(self, 'gravity_m_per_s2', GRAVITY_MAX_M_PER_S2, GRAVITY_REASON)
        elements = sum(s.elements for s in self.sections)
        if elements > ELEMENTS_MAX:
            raise ConfigValueError('sections', f'{elements} elements in all; at most '
                                               f'{ELEMENTS_MAX} ({ELEMENTS_REASON})')
        length = self.length_m
        if length > LENGTH_MAX_M:
            raise ConfigValueError('sections', f'the string is {length:g} m long; at most '
                                               f'{LENGTH_MAX_M:g} m ({LENGTH_REASON})')
        hole = self.borehole.diameter_m
        for section in self.sections:
            if section.outer_diameter_m >= hole:
                raise ConfigValueError(
                    f'sections.{section.name}.outer_diameter_m',
                    f'{section.outer_diameter_m} m does not fit in the borehole '
                    f'(borehole.diameter_m = {hole} m)')
        for stabilizer in self.stabilizers:
            if stabilizer.position_m > length:
                raise ConfigValueError(
                    f'stabilizers.{stabilizer.name}.position_m',
                    f'{stabilizer.position_m} m is below the bit (string length {length} m)')
        if self.physics.bit_rock and self.bit_rock.static_weight_on_bit_n > 0:
            raise ConfigValueError(
                'bit_rock.static_weight_on_bit_n',
                'must be <= 0 while the bit drills (the rock pushes the bit up; forces are '
                f'positive downwards), got {self.bit_rock.static_weight_on_bit_n}')
        if self.physics.fluid and self.fluid.inlet_speed_m_per_s > 0:
            for section in self.sections:
                if section.inner_diameter_m <= 0:
                    raise ConfigValueError(
                        f'sections.{section.name}.inner_diameter_m',
                        'a solid section cannot carry the mud flow '
                        '(fluid.inlet_speed_m_per_s > 0)')
        clearance = max((hole - s.outer_diameter_m) / 2 for s in self.sections)
        where = 'largest clearance'
        if self.initial_conditions.lateral_shape == 'bha_half_sine':
            clearance, where = (hole - self.sections[-1].outer_diameter_m) / 2, 'BHA clearance'
        if self.physics.contact and self.initial_conditions.lateral_deflection_m > clearance:
            raise ConfigValueError(
                'initial_conditions.lateral_deflection_m',
                f'{self.initial_conditions.lateral_deflection_m:g} m does not fit in the hole '
                f'({where} {clearance:g} m): the string would start inside the wall')
        imbalance = self.excitation.imbalance
        if imbalance.enabled and imbalance.position_m > length:
            raise ConfigValueError(
                'excitation.imbalance.position_m',
                f'{imbalance.position_m} m is below the bit (string length {length} m)')
        pattern = self.excitation.bottom_hole_pattern
        if pattern.enabled and self.bit_rock.contact_stiffness_n_per_m is None:
            raise ConfigValueError(
                'excitation.bottom_hole_pattern.enabled',
                'a lobed hole bottom needs a compliant rock (bit_rock.contact_stiffness_n_per_m '
                'is null: a rigid rock would stop the bit on each lobe within one step)')
        for index, x in enumerate(self.output.stations_m):
            if x > length:
                raise ConfigValueError(
                    f'output.stations_m.{index}',
                    f'{x} m is below the bit (string length {length} m)')

    @property
    def length_m(self) -> float:
        """Total string length L, m."""
        return float(sum(s.length_m for s in self.sections))
