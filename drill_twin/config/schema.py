"""
The configuration of a drill-string model as frozen dataclasses.

Every quantity is SI and carries its unit in its name. The checks here refuse input
that is physically impossible; the loader (``loader.py``) turns YAML into these objects
and prefixes every error with the key path it came from.

Conventions (see ``docs/MODEL-CHOICES.md``): x is the string axis pointing down from the
top (x = 0) to the bit; forces along x are positive downwards, so the weight on bit of the
paper (``f_bit``) is negative in compression.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

SectionKind = Literal['drill_pipe', 'heavy_weight_pipe', 'drill_collar', 'other']
AxialEnd = Literal['free', 'fixed']
TorsionTop = Literal['driven', 'free']
TorsionBit = Literal['free', 'fixed']
LateralEnd = Literal['clamped', 'pinned', 'free']
CoriolisForm = Literal['gyroscopic', 'paper']
InitialShape = Literal['first_lateral_mode', 'half_sine', 'bha_half_sine']


class ConfigValueError(ValueError):
    """
    A value that cannot describe a real drill string.

    ``key`` is the dotted path relative to the object that raised it; the loader
    prefixes the path of that object.
    """

    def __init__(self, key: str, message: str):
        super().__init__(f'{key}: {message}')
        self.key = key
        self.message = message


def _positive(obj, *names: str) -> None:
    for name in names:
        value = getattr(obj, name)
        if not (math.isfinite(value) and value > 0.0):
            raise ConfigValueError(name, f'must be a finite positive number, got {value!r}')


def _non_negative(obj, *names: str) -> None:
    for name in names:
        value = getattr(obj, name)
        if not (math.isfinite(value) and value >= 0.0):
            raise ConfigValueError(name, f'must be a finite number >= 0, got {value!r}')


def _at_most(obj, name: str, high: float, reason: str) -> None:
    """Refuse |value| above the plausible ``high`` (``reason`` says why it is implausible)."""
    value = getattr(obj, name)
    if abs(value) > high:
        bound = f'at most {high:g}' if value > 0 else f'at least {-high:g}'
        raise ConfigValueError(name, f'must be {bound} ({reason}), got {value:g}')


def _at_least(obj, name: str, low: float, reason: str) -> None:
    value = getattr(obj, name)
    if value < low:
        raise ConfigValueError(name, f'must be at least {low:g} ({reason}), got {value:g}')


# Plausibility: every bound lies beyond any real drill string, so that a value outside it is
# a mistake (a unit slip, an exponent too many), and the model built from values inside it
# stays within floating-point range. Each bound says why (the message carries the reason).
LENGTH_MAX_M = 20_000.0
LENGTH_REASON = 'no well is longer: Kola SG-3 12 262 m, extended-reach wells 15 km'
HOLE_DIAMETER_MAX_M = 2.0
HOLE_DIAMETER_REASON = 'no rotary-drilled hole is wider: conductor holes are about 1.1 m'
ELEMENTS_MAX = 1000
ELEMENTS_REASON = ('the modal analysis is dense: a 6 (N + 1) square mode-shape matrix, '
                   '290 MB at 1000 elements; the paper uses 56')
YOUNG_MODULUS_RANGE_PA = (1.0e9, 1.2e12)
YOUNG_MODULUS_REASON = 'from polymers, 1 GPa, to diamond, 1.2 TPa; steel is 210 GPa'
SOLID_DENSITY_RANGE_KG_PER_M3 = (500.0, 25_000.0)
SOLID_DENSITY_REASON = 'from wood, 500, to osmium, 22 600; steel is 7 850'
SPRING_STIFFNESS_MAX_N_PER_M = 1.0e11
SPRING_STIFFNESS_REASON = ('a solid steel plug filling a 0.6 m hole, one diameter long: '
                           'E pi D / 4 = 1e11 N/m')
FRICTION_COEFFICIENT_MAX = 2.0
FRICTION_REASON = 'steel rubs on rock with 0.1 to 0.6'
MUD_DENSITY_MAX_KG_PER_M3 = 3000.0
MUD_DENSITY_REASON = 'the heaviest drilling muds are about 2 500 kg/m3'
MUD_SPEED_MAX_M_PER_S = 30.0
MUD_SPEED_REASON = 'five times the fastest mud flow in drill pipe, about 6 m/s'
DRAG_COEFFICIENT_MAX = 1.0
DRAG_REASON = 'eighty times the paper\'s skin-friction coefficient, 0.0125'
GRAVITY_MAX_M_PER_S2 = 30.0
GRAVITY_REASON = 'no planet of the solar system pulls harder: Jupiter 24.8, Earth 9.81'
WEIGHT_ON_BIT_MAX_N = 1.0e7
WEIGHT_ON_BIT_REASON = 'twenty times the largest weights on bit, about 0.5 MN'
BIT_MASS_MAX_KG = 1.0e6
BIT_MASS_REASON = ('ten times the heaviest bottom-hole assemblies, about 100 t, were they '
                   'lumped at the bit')
BIT_INERTIA_MAX_KG_M2 = 1.0e5
BIT_INERTIA_REASON = 'twice a 100 t steel cylinder filling a 2 m hole, 5e4 kg m2'
TOP_DRIVE_SPEED_MAX_HZ = 10.0
TOP_DRIVE_SPEED_REASON = 'twice the fastest top drives, 300 rpm = 5 Hz'
TOP_DRIVE_ACCELERATION_MAX_RAD_PER_S2 = 1000.0
TOP_DRIVE_ACCELERATION_REASON = 'a top drive takes about a second, not 0.03 s, to full speed'
HOOK_LOAD_MAX_N = 1.0e8
HOOK_LOAD_REASON = 'ten times the rated hook load of the largest rigs, about 1 000 t'
MASS_DAMPING_MAX_PER_S = 100.0
MASS_DAMPING_REASON = 'more would critically damp every mode below 8 Hz'
STIFFNESS_DAMPING_MAX_S = 0.1
STIFFNESS_DAMPING_REASON = 'more would critically damp every mode above 3.2 Hz'
TIME_STEP_MAX_S = 0.1
TIME_STEP_REASON = ('ten steps per period of 1 Hz, the harmonics of the 0.2 Hz stick-slip; '
                    'the paper uses 5 ms')
TOLERANCE_MAX = 0.1
TOLERANCE_REASON = 'more would accept a Newton step with 10 % of its increment unresolved'
ITERATIONS_MAX = 1000
ITERATIONS_REASON = 'Newton\'s method converges in a few iterations or not at all'


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
        _positive(self, 'length_m', 'outer_diameter_m', 'young_modulus_pa',
                  'density_kg_per_m3', 'shear_correction_factor')
        _non_negative(self, 'inner_diameter_m')
        if self.inner_diameter_m >= self.outer_diameter_m:
            raise ConfigValueError(
                'inner_diameter_m',
                f'must be smaller than outer_diameter_m ({self.outer_diameter_m} m), '
                f'got {self.inner_diameter_m} m')
        if self.elements < 1:
            raise ConfigValueError('elements', f'must be at least 1, got {self.elements}')
        _at_most(self, 'elements', ELEMENTS_MAX, ELEMENTS_REASON)
        _at_most(self, 'length_m', LENGTH_MAX_M, LENGTH_REASON)
        _at_most(self, 'outer_diameter_m', HOLE_DIAMETER_MAX_M, HOLE_DIAMETER_REASON)
        _at_least(self, 'young_modulus_pa', YOUNG_MODULUS_RANGE_PA[0], YOUNG_MODULUS_REASON)
        _at_most(self, 'young_modulus_pa', YOUNG_MODULUS_RANGE_PA[1], YOUNG_MODULUS_REASON)
        _at_least(self, 'density_kg_per_m3', SOLID_DENSITY_RANGE_KG_PER_M3[0],
                  SOLID_DENSITY_REASON)
        _at_most(self, 'density_kg_per_m3', SOLID_DENSITY_RANGE_KG_PER_M3[1],
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
        _non_negative(self, 'position_m', 'stiffness_n_per_m')
        _at_most(self, 'stiffness_n_per_m', SPRING_STIFFNESS_MAX_N_PER_M, SPRING_STIFFNESS_REASON)


@dataclass(frozen=True, slots=True, kw_only=True)
class Borehole:
    """
    The hole and the impact/rubbing law between string and wall (Eq. 17-18).

    tangential_friction: the wall's friction as a force at the contact point (it can drive
    backward whirl) instead of the paper's rubbing torque alone (dynamics/contact.py).
    """

    diameter_m: float
    contact_stiffness_n_per_m: float
    friction_coefficient: float
    friction_regularization_rad_per_s: float
    tangential_friction: bool = False

    def __post_init__(self):
        _positive(self, 'diameter_m', 'contact_stiffness_n_per_m',
                  'friction_regularization_rad_per_s')
        _non_negative(self, 'friction_coefficient')
        _at_most(self, 'diameter_m', HOLE_DIAMETER_MAX_M, HOLE_DIAMETER_REASON)
        _at_most(self, 'contact_stiffness_n_per_m', SPRING_STIFFNESS_MAX_N_PER_M,
                 SPRING_STIFFNESS_REASON)
        _at_most(self, 'friction_coefficient', FRICTION_COEFFICIENT_MAX, FRICTION_REASON)


@dataclass(frozen=True, slots=True, kw_only=True)
class Fluid:
    """Drilling mud inside the string and in the annulus (Eq. 19-23)."""

    density_kg_per_m3: float
    inlet_speed_m_per_s: float
    drag_coefficient: float
    viscous_damping_n_s_per_m2: float
    coriolis: CoriolisForm

    def __post_init__(self):
        _positive(self, 'density_kg_per_m3')
        _non_negative(self, 'inlet_speed_m_per_s', 'drag_coefficient',
                      'viscous_damping_n_s_per_m2')
        _at_most(self, 'density_kg_per_m3', MUD_DENSITY_MAX_KG_PER_M3, MUD_DENSITY_REASON)
        _at_most(self, 'inlet_speed_m_per_s', MUD_SPEED_MAX_M_PER_S, MUD_SPEED_REASON)
        _at_most(self, 'drag_coefficient', DRAG_COEFFICIENT_MAX, DRAG_REASON)


@dataclass(frozen=True, slots=True, kw_only=True)
class BitRock:
    """The bit-rock law of Eq. 24-26 and the static bit reaction of the prestress."""

    a1_m_per_s: float
    a2_m_per_n_s: float
    a3_m_per_rad: float
    a4_n_rad: float
    a5_n_m: float
    regularization_rad_per_s: float
    static_weight_on_bit_n: float
    random_law_rop_scale_m_per_s: float = 1e-4
    """Near ROP = 0 the random law is blended into the mean law over this ROP scale."""
    contact_stiffness_n_per_m: float | None = None
    """The rock's contact stiffness under the bit (not in the paper): the bit resting on bottom
    presses the rock elastically by f / k, and a landing is stopped by that spring instead of
    within one time step. None: a rigid rock (the law alone)."""

    def __post_init__(self):
        _positive(self, 'a2_m_per_n_s', 'regularization_rad_per_s',
                  'random_law_rop_scale_m_per_s')
        if self.contact_stiffness_n_per_m is not None:
            _positive(self, 'contact_stiffness_n_per_m')
        _non_negative(self, 'a1_m_per_s', 'a3_m_per_rad', 'a4_n_rad', 'a5_n_m')
        if not math.isfinite(self.static_weight_on_bit_n):
            raise ConfigValueError('static_weight_on_bit_n', 'must be finite')
        _at_most(self, 'static_weight_on_bit_n', WEIGHT_ON_BIT_MAX_N, WEIGHT_ON_BIT_REASON)


@dataclass(frozen=True, slots=True, kw_only=True)
class Bit:
    """Lumped rigid bit (and motor) at the bottom node."""

    mass_kg: float
    polar_inertia_kg_m2: float

    def __post_init__(self):
        _non_negative(self, 'mass_kg', 'polar_inertia_kg_m2')
        _at_most(self, 'mass_kg', BIT_MASS_MAX_KG, BIT_MASS_REASON)
        _at_most(self, 'polar_inertia_kg_m2', BIT_INERTIA_MAX_KG_M2, BIT_INERTIA_REASON)


@dataclass(frozen=True, slots=True, kw_only=True)
class Operation:
    """The rig's set point: top-drive speed and hook load."""

    top_drive_speed_hz: float
    top_drive_acceleration_rad_per_s2: float
    """How fast the top-drive speed follows a new command."""
    hook_load_n: float | None = None
    """None: the hook load of the prestressed state, so that the mean WOB is the static one."""

    def __post_init__(self):
        if not math.isfinite(self.top_drive_speed_hz):
            raise ConfigValueError('top_drive_speed_hz', 'must be finite')
        _at_most(self, 'top_drive_speed_hz', TOP_DRIVE_SPEED_MAX_HZ, TOP_DRIVE_SPEED_REASON)
        _positive(self, 'top_drive_acceleration_rad_per_s2')
        _at_most(self, 'top_drive_acceleration_rad_per_s2', TOP_DRIVE_ACCELERATION_MAX_RAD_PER_S2,
                 TOP_DRIVE_ACCELERATION_REASON)
        if self.hook_load_n is not None:
            if not math.isfinite(self.hook_load_n):
                raise ConfigValueError('hook_load_n', 'must be finite or null')
            if self.hook_load_n < 0:
                raise ConfigValueError('hook_load_n', f'must be >= 0 (a hook can only pull), '
                                                      f'got {self.hook_load_n:g}')
            _at_most(self, 'hook_load_n', HOOK_LOAD_MAX_N, HOOK_LOAD_REASON)

    @property
    def top_drive_speed_rad_per_s(self) -> float:
        """Omega_x in rad/s."""
        return 2.0 * math.pi * self.top_drive_speed_hz


@dataclass(frozen=True, slots=True, kw_only=True)
class Boundary:
    """End conditions. The top is held by the hook (axially free) and driven in rotation."""

    top_axial: AxialEnd
    top_torsion: TorsionTop
    top_lateral: LateralEnd
    bit_axial: AxialEnd
    bit_torsion: TorsionBit
    bit_lateral: LateralEnd


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
        _non_negative(self, 'mass_coefficient_per_s', 'stiffness_coefficient_s')
        _at_most(self, 'mass_coefficient_per_s', MASS_DAMPING_MAX_PER_S, MASS_DAMPING_REASON)
        _at_most(self, 'stiffness_coefficient_s', STIFFNESS_DAMPING_MAX_S,
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
class Integration:
    """
    Implicit Newmark (average acceleration) on the reduced model.

    contact_substeps: 1 (a fixed step) or 2, 4 (default), 8, 16: a member whose step makes
    a node touch or leave the borehole wall integrates that step again on dt / contact_substeps
    (the penalty law's kink makes the trapezoidal rule gain or lose energy at 5 ms;
    dynamics/simulator.py, docs/LATERAL.md). No cost while nothing touches the wall.
    """

    time_step_s: float
    tolerance: float
    max_iterations: int
    contact_substeps: int = 4

    def __post_init__(self):
        _positive(self, 'time_step_s', 'tolerance')
        if self.max_iterations < 1:
            raise ConfigValueError('max_iterations',
                                   f'must be at least 1, got {self.max_iterations}')
        if self.contact_substeps not in (1, 2, 4, 8, 16):
            raise ConfigValueError('contact_substeps',
                                   f'must be 1, 2, 4, 8 or 16, got {self.contact_substeps}')
        _at_most(self, 'time_step_s', TIME_STEP_MAX_S, TIME_STEP_REASON)
        _at_most(self, 'tolerance', TOLERANCE_MAX, TOLERANCE_REASON)
        _at_most(self, 'max_iterations', ITERATIONS_MAX, ITERATIONS_REASON)


@dataclass(frozen=True, slots=True, kw_only=True)
class InitialConditions:
    """Initial state: rigid axial and rotation speed plus a lateral deflection (Sect. 2.7)."""

    lateral_deflection_m: float
    lateral_shape: InitialShape
    steady_twist: bool = False
    """Start twisted by the steady torque on bit (no start-up transient); the paper starts
    untwisted."""

    def __post_init__(self):
        _non_negative(self, 'lateral_deflection_m')


@dataclass(frozen=True, slots=True, kw_only=True)
class Output:
    """What a simulation records."""

    stations_m: tuple[float, ...]
    record_interval_s: float

    def __post_init__(self):
        for index, x in enumerate(self.stations_m):
            if not (math.isfinite(x) and x >= 0):
                raise ConfigValueError(f'stations_m.{index}', f'must be >= 0, got {x}')
        _positive(self, 'record_interval_s')


# -- The rig's drives (issue 13): top drive and drawworks -------------------------------------
TopDriveMode = Literal['kinematic', 'dynamic']
DriveController = Literal['stiff', 'soft_torque', 'impedance']
DrawworksMode = Literal['hook_load', 'block_velocity', 'autodriller']
DRIVE_INERTIA_MAX_KG_M2 = 1.0e5
DRIVE_INERTIA_REASON = ('fifty times a large top drive (rotor and gearbox referred to the '
                        'main shaft, about 2 000 kg m^2)')
DRIVE_GAIN_MAX = 1.0e9
DRIVE_GAIN_REASON = 'a speed loop stiffer than 1 GN m per rad/s is a unit slip'
DRIVE_TORQUE_MAX_NM = 1.0e6
DRIVE_TORQUE_REASON = 'ten times the largest top drives (about 100 kN m)'
BLOCK_SPEED_MAX_M_PER_S = 5.0
BLOCK_SPEED_REASON = 'drawworks hoist at about 2 m/s at most'
LINE_STIFFNESS_MAX_N_PER_M = 1.0e10
LINE_STIFFNESS_REASON = 'a drill line of 12 lines of 1.5 in wire over 50 m is about 1e8 N/m'


@dataclass(frozen=True, slots=True, kw_only=True)
class TopDrive:
    """
    The top drive (docs/DRIVES.md).

    ``kinematic``: the paper's imposed speed (the string's top rotation follows the command at
    ``operation.top_drive_acceleration_rad_per_s2``); ``dynamic``: a rotor of ``inertia_kg_m2``
    (referred to the main shaft through the gearbox) under a PI speed controller whose motor
    torque is limited to ``torque_limit_nm``, driving the string's top, with the speed set-point
    shaped by ``controller``.

    ``impedance_nm_s_per_rad`` (N m s/rad) is derived from the string unless given: for
    ``impedance`` the top pipe's characteristic impedance zeta = I_p sqrt(rho k_s G), for
    ``soft_torque`` k_t / omega_1 (torsional stiffness over first torsional frequency).
    """

    mode: TopDriveMode = 'kinematic'
    inertia_kg_m2: float = 2000.0
    proportional_gain_nm_s_per_rad: float = 2.0e5
    integral_gain_nm_per_rad: float = 2.0e5
    torque_limit_nm: float = 80.0e3
    controller: DriveController = 'stiff'
    impedance_nm_s_per_rad: float | None = None
    """None: derived from the string (see the class docstring)."""
    soft_torque_corner_fraction: float = 0.5
    """soft_torque: high-pass corner of the torque feedback as a fraction of the first
    torsional frequency of the string (fixed top)."""
    mean_torque_time_constant_s: float = 10.0
    """impedance: the slowly varying mean torque (a first-order low-pass) that the speed
    set-point does not respond to, so the mean speed stays at the command."""

    def __post_init__(self):
        _positive(self, 'inertia_kg_m2', 'torque_limit_nm', 'soft_torque_corner_fraction',
                  'mean_torque_time_constant_s')
        _non_negative(self, 'proportional_gain_nm_s_per_rad', 'integral_gain_nm_per_rad')
        _at_most(self, 'inertia_kg_m2', DRIVE_INERTIA_MAX_KG_M2, DRIVE_INERTIA_REASON)
        _at_most(self, 'proportional_gain_nm_s_per_rad', DRIVE_GAIN_MAX, DRIVE_GAIN_REASON)
        _at_most(self, 'integral_gain_nm_per_rad', DRIVE_GAIN_MAX, DRIVE_GAIN_REASON)
        _at_most(self, 'torque_limit_nm', DRIVE_TORQUE_MAX_NM, DRIVE_TORQUE_REASON)
        if self.impedance_nm_s_per_rad is not None:
            _positive(self, 'impedance_nm_s_per_rad')
            _at_most(self, 'impedance_nm_s_per_rad', DRIVE_GAIN_MAX, DRIVE_GAIN_REASON)


@dataclass(frozen=True, slots=True, kw_only=True)
class Drawworks:
    """
    The axial input (docs/DRIVES.md).

    ``hook_load``: the paper's hook force (``operation.hook_load_n``); ``block_velocity``: the
    travelling block moves at ``block_velocity_m_per_s`` (down > 0) and holds the top through a
    drill line of ``line_stiffness_n_per_m`` and ``line_damping_n_s_per_m``, the hook load is
    measured; ``autodriller``: the block velocity regulated (PI) to hold
    ``weight_on_bit_setpoint_n`` (> 0, compression). In either the block's velocity changes at
    most at ``block_acceleration_max_m_per_s2`` (the drum's motor and brake).
    """

    mode: DrawworksMode = 'hook_load'
    block_velocity_m_per_s: float = 0.0
    block_acceleration_max_m_per_s2: float = 0.2
    line_stiffness_n_per_m: float = 2.0e7
    line_damping_n_s_per_m: float = 2.0e5
    block_speed_max_m_per_s: float | None = 1.0
    """The fastest the drum moves the block (m/s): in ``hook_load`` mode the brake holds the
    top's axial speed to it (dynamics/drawworks.HookBrake). None: the paper's bare hook force."""
    weight_on_bit_setpoint_n: float = 100.0e3
    autodriller_proportional_m_per_s_per_n: float = 1.0e-7
    autodriller_integral_m_per_s2_per_n: float = 5.0e-9
    autodriller_feed_rate_max_m_per_s: float = 0.02
    """The autodriller's ROP limit (m/s; 0.02 = 72 m/h, above the law's steady ROP over the
    envelope, 64 m/h at 30 rad/s and 300 kN): it never feeds line faster, and its integral is
    held within [0, this] (anti-windup)."""

    def __post_init__(self):
        if not math.isfinite(self.block_velocity_m_per_s):
            raise ConfigValueError('block_velocity_m_per_s', 'must be finite')
        _at_most(self, 'block_velocity_m_per_s', BLOCK_SPEED_MAX_M_PER_S, BLOCK_SPEED_REASON)
        _positive(self, 'line_stiffness_n_per_m', 'block_acceleration_max_m_per_s2',
                  'autodriller_feed_rate_max_m_per_s')
        _at_most(self, 'autodriller_feed_rate_max_m_per_s', BLOCK_SPEED_MAX_M_PER_S,
                 BLOCK_SPEED_REASON)
        if self.block_speed_max_m_per_s is not None:
            _positive(self, 'block_speed_max_m_per_s')
        _non_negative(self, 'line_damping_n_s_per_m', 'weight_on_bit_setpoint_n',
                      'autodriller_proportional_m_per_s_per_n',
                      'autodriller_integral_m_per_s2_per_n')
        _at_most(self, 'line_stiffness_n_per_m', LINE_STIFFNESS_MAX_N_PER_M,
                 LINE_STIFFNESS_REASON)
        _at_most(self, 'weight_on_bit_setpoint_n', WEIGHT_ON_BIT_MAX_N, WEIGHT_ON_BIT_REASON)
# -- end of the rig's drives ---------------------------------------------------------------------


# -- excitation (issue 12, section 2): what real strings have and the paper leaves out --------
IMBALANCE_MASS_MAX_KG = 1.0e5
IMBALANCE_MASS_REASON = 'the whole 200 m collar section of the paper weighs 57 t'
ECCENTRICITY_MAX_M = 0.5
ECCENTRICITY_REASON = 'a mass centre half a metre off the axis is outside any borehole'


@dataclass(frozen=True, slots=True, kw_only=True)
class Imbalance:
    """
    A mass imbalance or bent-collar eccentricity at one node of the string.

    The mass ``mass_kg`` (already part of the string's mass) has its centre at
    ``eccentricity_m`` from the section's axis, in the direction fixed to the section that is
    at angle theta_x (the local spin angle of the node, top-drive angle plus elastic twist) from
    the y axis. It loads the node with m e (theta_x'^2 cos + theta_x'' sin,
    theta_x'^2 sin - theta_x'' cos) on (v, w) and m e (v'' sin - w'' cos) - m e^2 theta_x''
    on theta_x (docs/LATERAL.md). Applied at the mesh node nearest ``position_m`` (m, down
    from the top).
    """

    enabled: bool = False
    position_m: float = 1500.0
    mass_kg: float = 0.0
    eccentricity_m: float = 0.0

    def __post_init__(self):
        _non_negative(self, 'position_m', 'mass_kg', 'eccentricity_m')
        _at_most(self, 'mass_kg', IMBALANCE_MASS_MAX_KG, IMBALANCE_MASS_REASON)
        _at_most(self, 'eccentricity_m', ECCENTRICITY_MAX_M, ECCENTRICITY_REASON)
        _at_most(self, 'position_m', LENGTH_MAX_M, LENGTH_REASON)

    @property
    def unbalance_kg_m(self) -> float:
        """Return m e (kg m); zero when disabled."""
        return self.mass_kg * self.eccentricity_m if self.enabled else 0.0


LOBES_MAX = 12
LOBES_REASON = 'roller-cone bits cut 3 lobes; more than 12 is no bottom-hole pattern'
LOBE_AMPLITUDE_MAX_M = 0.02
LOBE_AMPLITUDE_REASON = 'lobes of a bottom-hole pattern are millimetres high, not centimetres'


@dataclass(frozen=True, slots=True, kw_only=True)
class BottomHolePattern:
    """
    A lobed hole bottom: the rock's surface under the bit rises and falls as the bit turns.

    The undeformed bottom under the bit lies ``amplitude_m`` sin(``lobes`` phi) below the
    hole's mean bottom, phi the bit's spin angle (top-drive angle plus the bit's twist): the
    surface a roller-cone bit cuts (three lobes), the classic axial excitation of bit bounce
    (docs/LATERAL.md, section 11). The bit-rock law sets the bit's velocity relative to that
    surface. Needs a compliant rock (``bit_rock.contact_stiffness_n_per_m``).
    """

    enabled: bool = False
    lobes: int = 3
    amplitude_m: float = 0.0

    def __post_init__(self):
        if isinstance(self.lobes, bool) or not isinstance(self.lobes, int) or self.lobes < 1:
            raise ConfigValueError('lobes', f'must be a whole number >= 1, got {self.lobes!r}')
        _at_most(self, 'lobes', LOBES_MAX, LOBES_REASON)
        _non_negative(self, 'amplitude_m')
        _at_most(self, 'amplitude_m', LOBE_AMPLITUDE_MAX_M, LOBE_AMPLITUDE_REASON)

    @property
    def height_m(self) -> float:
        """Return the lobes' amplitude (m); zero when disabled."""
        return self.amplitude_m if self.enabled else 0.0


@dataclass(frozen=True, slots=True, kw_only=True)
class Excitation:
    """Sources of excitation outside the paper's model (all off by default)."""

    imbalance: Imbalance = field(default_factory=Imbalance)
    bottom_hole_pattern: BottomHolePattern = field(default_factory=BottomHolePattern)


KineticCouplingSign = Literal['derived', 'printed']
StrainKinematics = Literal['invariant', 'printed_elastic', 'printed_absolute']
StiffnessDamping = Literal['fixed_frame', 'rotating_frame']


@dataclass(frozen=True, slots=True, kw_only=True)
class LateralReadings:
    """
    Readings of the paper tested for its lateral response (issue 12, section 1).

    The defaults are the project's readings (docs/MODEL-CHOICES.md, docs/LATERAL.md).

    kinetic_coupling: 'derived' (T_c = -rho I_p theta_x' theta_y theta_z', the sign that
    follows from the rotation sequence) or 'printed' (Eq. 8-11 as printed: the opposite).
    strain_kinematics: Eq. 15 'invariant' (the section twisted, then tilted: the energy does
    not depend on the spin angle) or as printed (u_x = u - y theta_z + z theta_y), with
    theta_x the elastic twist ('printed_elastic') or the absolute angle, top drive's included
    ('printed_absolute'); docs/LATERAL.md, section 4.
    stiffness_damping: Rayleigh's beta K_t acting on the velocities in the fixed frame
    ('fixed_frame', the paper's [C] u') or on the strain rates of the spinning string
    ('rotating_frame': internal damping, which adds the circulatory force of
    dynamics/rotating_damping.py); docs/LATERAL.md, section 4.
    """

    kinetic_coupling: KineticCouplingSign = 'derived'
    strain_kinematics: StrainKinematics = 'invariant'
    stiffness_damping: StiffnessDamping = 'fixed_frame'


@dataclass(frozen=True, slots=True, kw_only=True)
class DrillStringConfig:
    """A whole vertical drill string, its hole, fluid, bit and the model choices."""

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
        _positive(self, 'gravity_m_per_s2')
        _at_most(self, 'gravity_m_per_s2', GRAVITY_MAX_M_PER_S2, GRAVITY_REASON)
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
