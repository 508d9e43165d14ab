"""How a run is integrated, from what state it starts and what it records."""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Literal

from drill_twin.config.bounds import (
    ITERATIONS_MAX, ITERATIONS_REASON, TIME_STEP_MAX_S, TIME_STEP_REASON, TOLERANCE_MAX,
    TOLERANCE_REASON)
from drill_twin.config.checks import at_least, at_most, ConfigValueError, non_negative, positive

TIME_STEP_MIN_S = 1.0e-5
TIME_STEP_MIN_REASON = ('a step takes about 0.2 ms of computing: a finer one needs more than '
                        '20 s per simulated second, the pre-flight\'s 0.25 s alone 25 000 '
                        'steps; the paper uses 5 ms')
"""The smallest time step a configuration may ask for (s)."""

InitialShape = Literal['first_lateral_mode', 'half_sine', 'bha_half_sine']


@dataclass(frozen=True, slots=True, kw_only=True)
class Integration:
    """
    Implicit Newmark (average acceleration) on the reduced model.

    contact_substeps: 1 (a fixed step) or 2, 4 (default), 8, 16: a member whose step makes
    a node touch or leave the borehole wall integrates that step again on dt / contact_substeps
    (the penalty law's kink makes the trapezoidal rule gain or lose energy at 5 ms;
    integrator/simulator.py, docs/LATERAL.md). No cost while nothing touches the wall.
    """

    time_step_s: float
    tolerance: float
    max_iterations: int
    contact_substeps: int = 4

    def __post_init__(self):
        positive(self, 'time_step_s', 'tolerance')
        if self.max_iterations < 1:
            raise ConfigValueError('max_iterations',
                                   f'must be at least 1, got {self.max_iterations}')
        if self.contact_substeps not in (1, 2, 4, 8, 16):
            raise ConfigValueError('contact_substeps',
                                   f'must be 1, 2, 4, 8 or 16, got {self.contact_substeps}')
        at_most(self, 'time_step_s', TIME_STEP_MAX_S, TIME_STEP_REASON)
        at_least(self, 'time_step_s', TIME_STEP_MIN_S, TIME_STEP_MIN_REASON)
        at_most(self, 'tolerance', TOLERANCE_MAX, TOLERANCE_REASON)
        at_most(self, 'max_iterations', ITERATIONS_MAX, ITERATIONS_REASON)


@dataclass(frozen=True, slots=True, kw_only=True)
class InitialConditions:
    """Initial state: rigid axial and rotation speed plus a lateral deflection (Sect. 2.7)."""

    lateral_deflection_m: float
    lateral_shape: InitialShape
    steady_twist: bool = False
    """Start twisted by the steady torque on bit (no start-up transient); the paper starts
    untwisted."""

    def __post_init__(self):
        non_negative(self, 'lateral_deflection_m')


@dataclass(frozen=True, slots=True, kw_only=True)
class Output:
    """What a simulation records."""

    stations_m: tuple[float, ...]
    record_interval_s: float

    def __post_init__(self):
        for index, x in enumerate(self.stations_m):
            if not (math.isfinite(x) and x >= 0):
                raise ConfigValueError(f'stations_m.{index}', f'must be >= 0, got {x}')
        positive(self, 'record_interval_s')
