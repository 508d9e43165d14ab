"""
Pre-flight check: refuse a configuration the model cannot represent, before a run starts.

Three stages, each a few hundred milliseconds at most:

1. The model is built (finite elements, prestress, normal modes, reduced system). A numerical
   failure there (an overflow, a singular or non-finite matrix) is a :class:`PreflightError`
   instead of a traceback.
2. The operating point: the hook load and the static bit reaction are checked against the
   string's weight as the model counts it, and the bit-rock law's steady state at the
   configured top-drive speed and weight on bit (Eq. 24, regularised as in
   :meth:`~drill_twin.model.bit_rock.BitRockLaw.steady_rop`) must be physically
   plausible: a ROP that is finite, not negative (the rock cannot push the bit back up the
   hole) and at most :data:`ROP_MAX_M_PER_S`; a torque on bit the string can carry
   (:func:`torque_capacity_nm`).
3. A short integration (:data:`SHORT_RUN_S` of simulated time) must neither diverge nor
   leave the plausible range of ROP and bit speed.

With the default configuration the steady state is ROP 2.62 mm/s and TOB -5.56 kN m at
5.215 rad/s and -100 kN, against a capacity of 450 kN m. Pure numerical core: no rclpy.

The steady weight on bit is the hook-load balance f_c + (H - H_S) (docs/MODEL-CHOICES.md,
"Hook load and WOB"); the Rayleigh drag alpha M ROP on the rigid axial motion is left out
(5 N, 5e-5 of the weight on bit, at the default operating point).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from threadpoolctl import threadpool_limits

from drill_twin.config.schema import DrillStringConfig
from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.model.reduced_system import ReducedSystem, build_reduced_system
from drill_twin.integrator.simulator import SimulationDiverged, Simulator
from drill_twin.rig.rig import Rig
from drill_twin.fem.model import FiniteElementModel
from drill_twin.modal.reduced_basis import ReducedBasis, modal_analysis

ROP_MAX_M_PER_S = 0.1
"""360 m/h: faster than any drilling on record (soft formations: 100 to 200 m/h). A law that
drills faster at the operating point has constants out of scale (e.g. a2 a million times
the paper's)."""

BIT_SPEED_MAX_RAD_PER_S = 100.0
"""950 rpm. In this model the bit turns only through the string: its steady speed is the
top drive's (at most 10 Hz = 63 rad/s by the schema) and stick-slip peaks reach two to
three times the mean; more than 100 rad/s during the short run means a runaway."""

SHEAR_STRAIN_LIMIT = 0.02
"""Largest shear strain at the outer surface of a section: twice the torsional yield strain
of the strongest drill-string materials (S-135 steel: 537 MPa / 81 GPa = 0.66 %; titanium
and aluminium alloys about 1.1 %). The model is linear-elastic: a torque beyond this would
have twisted the string off (:func:`torque_capacity_nm`)."""

SHORT_RUN_S = 0.25
"""Simulated time of the short integration: 50 steps of the paper's 5 ms, enough for a law
that cannot be integrated to diverge (1e12 N rad for a4 fails within 0.6 s, but is caught
by the steady torque first) and cheap (a fraction of a second)."""


class PreflightError(ValueError):
    """
    A configuration the model cannot represent or integrate.

    ``key``: the configuration key to blame ('' for the configuration as a whole);
    ``related``: further keys a user may have changed to cause it (for attributing the
    error to ``--set``); ``message``: one line.
    """

    def __init__(self, key: str, message: str, related: tuple[str, ...] = ()):
        super().__init__(f'{key}: {message}' if key else message)
        self.key = key
        self.message = message
        self.related = tuple(related)


@dataclass(frozen=True)
class OperatingPoint:
    """
    The steady state the configuration asks for (SI units, forces positive downwards).

    speed_rad_per_s: top-drive (= steady bit) speed; weight_on_bit_n: f_bit (< 0 in
    compression); hook_load_n: H; string_weight_n: the hook load at which the bit just
    leaves the rock (H_S - f_c: the string's weight as the model counts it, in air, MODEL.md;
    None without prestress); rop_m_per_s, torque_on_bit_nm: the bit-rock law's steady state;
    torque_capacity_nm: the largest torque the string carries (:func:`torque_capacity_nm`).
    """

    speed_rad_per_s: float
    weight_on_bit_n: float
    hook_load_n: float
    string_weight_n: float | None
    rop_m_per_s: float
    torque_on_bit_nm: float
    torque_capacity_nm: float


@dataclass(frozen=True)
class PreflightResult:
    """
    Hold the model built during the check, for the run to reuse, and the operating point.

    The operating point is None without the bit-rock law.
    """

    model: FiniteElementModel
    basis: ReducedBasis
    system: ReducedSystem
    operating_point: OperatingPoint | None


def preflight(config: DrillStringConfig, short_run_s: float = SHORT_RUN_S) -> PreflightResult:
    """Build the model and check it (module docstring); raises :class:`PreflightError`."""
    model, basis, system = build_model(config, reduced_system=True)
    point = check_operating_point(config, model) if config.physics.bit_rock else None
    if short_run_s > 0:
        check_short_run(config, system, short_run_s)
    return PreflightResult(model, basis, system, point)


def build_model(config: DrillStringConfig, reduced_system: bool = True):
    """
    (model, basis, reduced system or None) of ``config``.

    A numerical failure is a :class:`PreflightError` naming it. Overflow, invalid and
    divide-by-zero operations raise instead of warning (underflow is harmless and allowed).
    """
    try:
        with np.errstate(over='raise', invalid='raise', divide='raise'):
            model, _, basis = modal_analysis(config)
            system = build_reduced_system(model, basis) if reduced_system else None
    except (ArithmeticError, ValueError, np.linalg.LinAlgError, scipy.linalg.LinAlgError,
            RuntimeError) as error:
        raise PreflightError('', f'the model cannot be built from it: {_first_line(error)}') \
            from None
    return model, basis, system


def torque_capacity_nm(config: DrillStringConfig) -> float:
    """
    Return the largest torque every section carries.

    SHEAR_STRAIN_LIMIT G J / r_o of the weakest, with J = pi (D_o^4 - D_i^4) / 32 (N m).
    """
    capacities = []
    for section in config.sections:
        polar = math.pi * (section.outer_diameter_m ** 4 - section.inner_diameter_m ** 4) / 32
        capacities.append(SHEAR_STRAIN_LIMIT * section.shear_modulus_pa * polar
                          / (section.outer_diameter_m / 2))
    return min(capacities)


def operating_point(config: DrillStringConfig, model: FiniteElementModel) -> OperatingPoint:
    """Return the steady state of the bit-rock law at the configured top-drive speed, hook load."""
    static = config.bit_rock.static_weight_on_bit_n
    hook = config.operation.hook_load_n
    if config.physics.prestress:
        hook_static = model.prestress.hook_load_n             # H_S: holds the string at f_c
        weight = hook_static - static
        wob = static if hook is None else static + (hook - hook_static)
        hook = hook_static if hook is None else hook
    else:
        weight, wob, hook = None, static, 0.0 if hook is None else hook
    law = BitRockLaw.from_config(config.bit_rock)
    speed = config.operation.top_drive_speed_rad_per_s
    with np.errstate(all='ignore'):
        rop = float(law.steady_rop(speed, wob))
        torque = float(law.mean(rop, speed)[1]) if math.isfinite(rop) else math.nan
    return OperatingPoint(speed_rad_per_s=speed, weight_on_bit_n=wob, hook_load_n=hook,
                          string_weight_n=weight, rop_m_per_s=rop, torque_on_bit_nm=torque,
                          torque_capacity_nm=torque_capacity_nm(config))


def check_operating_point(config: DrillStringConfig,
                          model: FiniteElementModel) -> OperatingPoint:
    """Return the operating point if plausible (module docstring), else :class:`PreflightError`."""
    p = operating_point(config, model)
    if p.string_weight_n is not None:
        weight = p.string_weight_n
        if config.operation.hook_load_n is not None and p.hook_load_n >= weight:
            raise PreflightError(
                'operation.hook_load_n',
                f'{p.hook_load_n / 1e3:.1f} kN lifts the whole string off the rock (it '
                f'weighs {weight / 1e3:.1f} kN as the model counts it: the weight in air, no '
                'net buoyancy): nothing would hold it; give less than its weight')
        if p.string_weight_n <= 0 or model.prestress.hook_load_n < 0:
            raise PreflightError(
                'bit_rock.static_weight_on_bit_n',
                f'{config.bit_rock.static_weight_on_bit_n / 1e3:.1f} kN is more than the '
                f'string weighs ({max(weight, 0.0) / 1e3:.1f} kN as the model counts it): the '
                'hook would have to push it down', related=('sections', 'gravity_m_per_s2'))
    where = (f'at the operating point ({p.speed_rad_per_s:.3g} rad/s, weight on bit '
             f'{p.weight_on_bit_n / 1e3:.4g} kN)')
    related = ('operation', 'bit_rock')
    if not math.isfinite(p.rop_m_per_s):
        raise PreflightError('bit_rock', f'the law gives no finite ROP {where}', related)
    if p.rop_m_per_s < 0:
        raise PreflightError(
            'bit_rock', f'the law gives a steady ROP of {_speed(p.rop_m_per_s)} {where}: the '
            'rock would push the bit back up the hole; it needs more weight on bit or other '
            'constants', related)
    if p.rop_m_per_s > ROP_MAX_M_PER_S:
        raise PreflightError(
            'bit_rock', f'the law gives a steady ROP of {_speed(p.rop_m_per_s)} {where}, '
            f'more than {ROP_MAX_M_PER_S:g} m/s ({ROP_MAX_M_PER_S * 3600:.0f} m/h, faster than '
            'any drilling)', related)
    if not abs(p.torque_on_bit_nm) <= p.torque_capacity_nm:
        raise PreflightError(
            'bit_rock', f'the law gives a steady torque on bit of '
            f'{_torque(p.torque_on_bit_nm)} {where}, more than the string carries '
            f'({_torque(p.torque_capacity_nm)} at {SHEAR_STRAIN_LIMIT:.0%} shear strain '
            'in its weakest section)', related + ('sections',))
    return p


def check_short_run(config: DrillStringConfig, system: ReducedSystem,
                    duration_s: float = SHORT_RUN_S) -> None:
    """
    Integrate ``duration_s`` of the mean model.

    Raise :class:`PreflightError` if it diverges or the bit leaves the plausible range (ROP, bit
    speed).
    """
    simulator = Simulator(config, system=system)
    rig = Rig(simulator)
    steps = max(1, math.ceil(duration_s / simulator.dt - 1e-9))
    with threadpool_limits(limits=1, user_api='blas'):          # small matrices (see run.py)
        for _ in range(steps):
            try:
                rig.step()
            except SimulationDiverged as error:
                raise PreflightError('', f'it cannot be integrated: {error}') from None
            _check_bit(simulator, duration_s)


def _check_bit(simulator: Simulator, duration_s: float) -> None:
    forces = simulator.last
    rop = float(np.max(np.abs(forces.rop_m_per_s)))
    speed = float(np.max(np.abs(forces.bit_speed_rad_per_s)))
    when = f'at t = {simulator.time_s:.3g} s of a {duration_s:g} s trial run'
    if not rop <= ROP_MAX_M_PER_S:
        raise PreflightError('', f'the bit moves at {_speed(rop)} {when}, more than '
                                 f'{ROP_MAX_M_PER_S:g} m/s: the model runs away')
    if not speed <= BIT_SPEED_MAX_RAD_PER_S:
        raise PreflightError('', f'the bit turns at {speed:.3g} rad/s {when}, more than '
                                 f'{BIT_SPEED_MAX_RAD_PER_S:g} rad/s: the model runs away')


def _speed(m_per_s: float) -> str:
    return f'{m_per_s * 1e3:.3g} mm/s' if abs(m_per_s) < 1.0 else f'{m_per_s:.3g} m/s'


def _torque(nm: float) -> str:
    return f'{nm / 1e3:.3g} kN m' if abs(nm) < 1e6 else f'{nm:.3g} N m'


def _first_line(error: BaseException) -> str:
    text = str(error).strip().splitlines()
    return text[0] if text else type(error).__name__
