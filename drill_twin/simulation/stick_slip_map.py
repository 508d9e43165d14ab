"""
The stick-slip map: the mean model over a grid of top-drive speed x weight on bit.

Every point is an independent run of the mean model (one task for an executor of
:mod:`drill_twin.uncertainty.executors`) at its top-drive speed Omega and its static weight on
bit WOB (> 0 in compression), set through the hook load H = W - WOB (W the string's weight
as the model counts it, :mod:`drill_twin.analysis.steady_drilling`). A point starts either
from steady drilling at (Omega, WOB) with the bit speed perturbed by
``perturbation_rad_per_s`` (``start='steady'``, the default: a small kick that the linear
stability analysis predicts will grow or decay), or from the configuration's own initial
state (``start='configured'``: untwisted string, as ``drill-twin simulate``). The
statistics are taken over the last ``window_s`` seconds; the linear stability of the
point's steady state is computed alongside (:mod:`drill_twin.analysis.linear_stability`).

Every speed and WOB of the grid is checked against the configuration's bounds before any
point runs (:func:`check_points`, :class:`MapPointError`); a speed of 0 is refused (the bit
does not turn: no steady drilling to start from or to linearise). A point whose integration
diverges is kept as a row of NaN statistics with ``failed = 1`` and the error in ``error``.
Points are returned in grid order (WOB-major: index = i_wob * n_speeds + i_speed) whatever the
executor, and a point computes the same numbers wherever it runs, so a map is reproducible
bit for bit.
"""
from __future__ import annotations

import dataclasses
import functools
import json
import math
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
from threadpoolctl import threadpool_limits

from drill_twin.config.checks import ConfigValueError
from drill_twin.config.loader import build_config, config_to_dict
from drill_twin.config.schema import DrillStringConfig
from drill_twin.analysis import kpi
from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.analysis.linear_stability import AxialTorsionalLinearisation, stability_grid
from drill_twin.model.reduced_system import build_reduced_system
from drill_twin.integrator.simulator import SimulationDiverged, Simulator
from drill_twin.rig.rig import Rig
from drill_twin.analysis.steady_drilling import hook_load_for, steady_coordinates, under_hook_load
from drill_twin.modal.reduced_basis import modal_analysis

RAD_PER_S_TO_RPM = 60.0 / (2.0 * math.pi)
SSI_STICK_SLIP = 0.5
"""SSI from which the torsional oscillation counts as stick-slip (half the mean speed)."""
SSI_FULL_STICK = 1.0
"""SSI from which the bit stops (a symmetric swing of the bit speed reaches zero)."""
SSI_STEADY = 0.05
"""SSI below which a simulated point counts as steady when compared with the linear
stability (a bit-speed swing under 5 % of the mean speed each way)."""
STARTS = ('steady', 'configured')
ZERO_SPEED_REASON = ('at 0 the bit does not turn: the bit-rock law, f = -ROP (omega^2 + e^2) / '
                     '(a2 omega^2), is singular there, with no steady drilling to start from '
                     'or to linearise')
"""Why a map has no point at zero top-drive speed."""
BOUNDARY_RESOLUTION = (81, 61)
"""Speeds x WOBs of the fine grid on which the linear stability boundary is drawn."""

COLUMNS = {
    'top_drive_speed_rad_per_s': 'top-drive speed Omega of the point (rad/s)',
    'top_drive_speed_rpm': 'the same in rpm',
    'weight_on_bit_n': 'static weight on bit of the point, > 0 in compression (N)',
    'hook_load_n': 'hook load that sets it, W - WOB (N)',
    'weight_on_bit_mean_n': 'measured mean weight on bit over the window, > 0 in '
                            'compression (N)',
    'stick_slip_severity': '(omega_max - omega_min) / (2 omega_mean) of the bit speed over '
                           'the window',
    'bit_speed_min_rad_per_s': 'smallest bit speed in the window (rad/s)',
    'bit_speed_max_rad_per_s': 'largest bit speed in the window (rad/s)',
    'bit_speed_mean_rad_per_s': 'mean bit speed over the window (rad/s)',
    'backward_rotation': '1 if the bit turned backwards (bit speed < 0) in the window',
    'lift_off_count': 'bit lift-off episodes that started in the window',
    'impact_count': 'borehole impacts (wall-contact episodes, all nodes) in the window',
    'rop_m_per_s': 'mean rate of penetration over the window: the rate the hole deepens (m/s)',
    'torque_on_bit_mean_nm': 'mean torque on bit over the window (t_bit, < 0 resisting; N m)',
    'mse_pa': 'Teale\'s mechanical specific energy over the window (Pa)',
    'oscillation_frequency_hz': 'frequency of the bit-speed oscillation in the window, from '
                                'its upward mean crossings (Hz; NaN with fewer than two)',
    'steady_rop_m_per_s': 'ROP of the bit-rock law at (Omega, WOB), steady drilling (m/s)',
    'steady_torque_on_bit_nm': 'torque on bit of the law at steady drilling (N m)',
    'growth_rate_per_s': 'real part of the least-stable eigenvalue of the linearised '
                         'axial-torsional model (1/s; > 0 unstable)',
    'frequency_hz': 'frequency of that eigenvalue, abs(imaginary part) / 2 pi (Hz)',
    'linearly_stable': '1 if the growth rate is negative',
    'linear_comparison': 'agree / disagree (linearly stable and SSI < 0.05, or unstable and '
                         'SSI >= 0.05), near_boundary (a grid neighbour lies on the other '
                         'side of the linear stability boundary) or failed',
    'failed': '1 if the integration diverged (statistics NaN)',
    'failed_time_s': 'simulated time of the failed step (s; NaN if none)',
    'wall_time_s': 'wall-clock time of the point\'s integration (s)',
    'error': 'the divergence message (empty if none)',
}


@dataclass(frozen=True)
class MapSpec:
    """What a map computes (SI units; speeds and WOBs are sorted); see the module docstring."""

    speeds_rad_per_s: tuple
    weights_on_bit_n: tuple
    duration_s: float
    window_s: float
    perturbation_rad_per_s: float = 0.5
    start: str = 'steady'
    seed: int | None = None

    def __post_init__(self):
        for name in ('speeds_rad_per_s', 'weights_on_bit_n'):
            values = tuple(sorted(float(v) for v in getattr(self, name)))
            object.__setattr__(self, name, values)
            if not values:
                raise ValueError(f'{name}: needs at least one value')
            if not all(math.isfinite(v) for v in values):
                raise ValueError(f'{name}: values must be finite')
            if len(set(values)) != len(values):
                raise ValueError(f'{name}: values must be distinct')
        if not all(v > 0 for v in self.speeds_rad_per_s):
            raise ValueError(f'speeds_rad_per_s: must be > 0 ({ZERO_SPEED_REASON}), got '
                             f'{self.speeds_rad_per_s[0]:g}')
        if not all(v > 0 for v in self.weights_on_bit_n):
            raise ValueError('weights_on_bit_n: must be > 0 (compression)')
        if not (math.isfinite(self.duration_s) and self.duration_s > 0):
            raise ValueError(f'duration: must be positive and finite, got {self.duration_s}')
        if not 0 < self.window_s <= self.duration_s:
            raise ValueError(f'window: must lie in (0, duration], got {self.window_s}')
        if not (math.isfinite(self.perturbation_rad_per_s) and self.perturbation_rad_per_s >= 0):
            raise ValueError('perturbation: must be finite and >= 0, got '
                             f'{self.perturbation_rad_per_s}')
        if self.start not in STARTS:
            raise ValueError(f'start: must be one of {", ".join(STARTS)}, got {self.start!r}')
        if self.seed is not None and self.seed < 0:
            raise ValueError(f'seed: must be >= 0, got {self.seed}')

    @property
    def shape(self) -> tuple[int, int]:
        """(n_wob, n_speed)."""
        return len(self.weights_on_bit_n), len(self.speeds_rad_per_s)

    def point(self, index: int) -> tuple[float, float]:
        """(Omega, WOB) of grid point ``index`` (WOB-major)."""
        i, j = divmod(index, len(self.speeds_rad_per_s))
        return self.speeds_rad_per_s[j], self.weights_on_bit_n[i]

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


@dataclass
class MapResult:
    """
    The rows of a map in grid order, and the linear stability on a fine grid.

    rows: one dict per point (keys: COLUMNS, plus 'index'); boundary_speeds_rad_per_s (n_s,),
    boundary_weights_on_bit_n (n_w,), boundary_growth_rate_per_s and
    boundary_frequency_hz (n_w, n_s): the linear stability over the map's range;
    boundary_steady_rop_m_per_s (n_w, n_s): the bit-rock law's steady ROP there (<= 0: the
    law cannot drill).
    """

    spec: MapSpec
    config: DrillStringConfig
    rows: list
    boundary_speeds_rad_per_s: np.ndarray
    boundary_weights_on_bit_n: np.ndarray
    boundary_growth_rate_per_s: np.ndarray
    boundary_frequency_hz: np.ndarray
    boundary_steady_rop_m_per_s: np.ndarray
    wall_s: float = 0.0
    workers: int = 1

    def column(self, name: str) -> np.ndarray:
        """Return a numeric column shaped like the grid, (n_wob, n_speed)."""
        return np.array([row[name] for row in self.rows], dtype=float).reshape(self.spec.shape)

    def failed_points(self) -> list[dict]:
        return [row for row in self.rows if row['failed']]


class MapPointError(ConfigValueError):
    """
    A speed or WOB of the grid that the configuration refuses.

    ``key``: the MapSpec field (speeds_rad_per_s or weights_on_bit_n); ``str()`` is
    ``key: message``, one line; it survives pickling (:class:`ConfigValueError`'s).
    """


def point_config(config: DrillStringConfig, system, speed_rad_per_s: float | None,
                 weight_on_bit_n: float | None) -> tuple[DrillStringConfig, float | None]:
    """
    Return (the configuration of a grid point, its hook load H = W - WOB in N).

    The configuration's operation at the point's top-drive speed and hook load (None keeps the
    configuration's own; the hook load returned is then None); raises
    :class:`~drill_twin.config.checks.ConfigValueError` (key ``operation.<field>``) if it
    refuses them.
    """
    changes = {}
    hook = None
    if speed_rad_per_s is not None:
        changes['top_drive_speed_hz'] = speed_rad_per_s / (2 * math.pi)
    if weight_on_bit_n is not None:
        hook = changes['hook_load_n'] = hook_load_for(system, weight_on_bit_n)
    try:
        operation = dataclasses.replace(config.operation, **changes)
    except ConfigValueError as error:
        raise ConfigValueError(f'operation.{error.key}', error.message) from None
    return dataclasses.replace(config, operation=operation), hook


def check_points(config: DrillStringConfig, spec: MapSpec) -> None:
    """
    Refuse a grid the configuration cannot run, before any point runs.

    Each speed and each WOB through :func:`point_config` (the other value the configuration's
    own); raises :class:`MapPointError` naming the first refused value.
    """
    _, system = _system_for(json.dumps(config_to_dict(config)))
    for speed in spec.speeds_rad_per_s:
        try:
            point_config(config, system, speed, None)
        except ConfigValueError as error:
            raise MapPointError('speeds_rad_per_s', f'{speed:g} rad/s: {error}') from None
    for wob in spec.weights_on_bit_n:
        try:
            point_config(config, system, None, wob)
        except ConfigValueError as error:
            raise MapPointError('weights_on_bit_n', f'{wob:g} N (hook load '
                                f'{hook_load_for(system, wob):.4g} N): {error}') from None


@functools.lru_cache(maxsize=4)
def _system_for(config_json: str):
    """Return the configuration and its reduced system, built once per process."""
    config = build_config(json.loads(config_json))
    model, _, basis = modal_analysis(config)
    return config, build_reduced_system(model, basis)


def run_point(config_json: str, spec: MapSpec, index: int) -> dict:
    """Integrate grid point ``index`` and return its row (see COLUMNS)."""
    config, system = _system_for(config_json)
    speed, wob = spec.point(index)
    law = BitRockLaw.from_config(config.bit_rock)
    configured, hook = point_config(config, system, speed, wob)
    steady = under_hook_load(system, law, speed, hook)
    stability = AxialTorsionalLinearisation(system).at(steady)
    row = {name: math.nan for name in COLUMNS}
    row.update(index=index, top_drive_speed_rad_per_s=speed,
               top_drive_speed_rpm=speed * RAD_PER_S_TO_RPM, weight_on_bit_n=wob,
               hook_load_n=hook, steady_rop_m_per_s=steady.rop_m_per_s,
               steady_torque_on_bit_nm=steady.torque_nm,
               growth_rate_per_s=stability.growth_rate_per_s,
               frequency_hz=stability.frequency_hz,
               linearly_stable=int(stability.stable), linear_comparison='', failed=0,
               error='')
    start = time.perf_counter()
    with threadpool_limits(limits=1, user_api='blas'):
        try:
            row.update(_integrate(configured, system, spec, steady, hook, index))
        except SimulationDiverged as error:
            row.update(failed=1, failed_time_s=error.time_s, error=str(error))
    row['wall_time_s'] = time.perf_counter() - start
    return row


def _perturbation(system, spec: MapSpec, index: int) -> np.ndarray:
    """
    Torsional rates (n_t,) that change the bit speed by about the spec's perturbation.

    The first torsional mode, or a random direction of the seed's stream (seed, index) with the
    same kinetic energy.
    """
    torsion = system.blocks['torsional']
    at_bit = torsion.shapes[system.bit_node]
    rates = np.zeros(at_bit.size)
    if rates.size == 0 or spec.perturbation_rad_per_s == 0:
        return rates
    size = spec.perturbation_rad_per_s / abs(at_bit[0])
    if spec.seed is None:
        rates[0] = size * np.sign(at_bit[0])
        return rates
    generator = np.random.default_rng(np.random.SeedSequence(spec.seed, spawn_key=(index,)))
    direction = generator.standard_normal(rates.size)
    return size * direction / np.linalg.norm(direction)


def _integrate(config, system, spec: MapSpec, steady, hook: float,
               index: int) -> dict:
    simulator = Simulator(config, system=system)
    rig = Rig(simulator)
    if spec.start == 'steady':
        q, q_rate = steady_coordinates(system, steady, hook, simulator.state.q,
                                       simulator.state.q_rate)
        q_rate[:, system.blocks['torsional'].columns] += _perturbation(system, spec, index)
        simulator.reset(q, q_rate)
    dt = simulator.dt
    steps = int(round(spec.duration_s / dt))
    first = steps - int(round(spec.window_s / dt))
    n = steps - first + 1
    series = {name: np.zeros(n) for name in ('speed', 'hole', 'wob', 'tob')}
    impacts = lift_offs = None
    for k in range(steps + 1):
        if k > 0:
            rig.step()
        if k < first:
            continue
        if impacts is None:
            impacts = int(simulator.impact_count[0])
            lift_offs = int(simulator.lift_off_count[0])
        last, j = simulator.last, k - first
        series['speed'][j] = last.bit_speed_rad_per_s[0]
        series['hole'][j] = simulator.hole_depth_m[0]
        series['wob'][j] = last.weight_on_bit_n[0]
        series['tob'][j] = last.torque_on_bit_nm[0]
    speed = series['speed']
    rop = (series['hole'][-1] - series['hole'][0]) / (dt * (n - 1))   # the hole's rate (m/s)
    return {
        'weight_on_bit_mean_n': -float(np.mean(series['wob'])),
        'stick_slip_severity': float(kpi.stick_slip_severity(speed)),
        'bit_speed_min_rad_per_s': float(np.min(speed)),
        'bit_speed_max_rad_per_s': float(np.max(speed)),
        'bit_speed_mean_rad_per_s': float(np.mean(speed)),
        'backward_rotation': int(np.min(speed) < 0),
        'lift_off_count': int(simulator.lift_off_count[0]) - lift_offs,
        'impact_count': int(simulator.impact_count[0]) - impacts,
        'rop_m_per_s': float(rop),
        'torque_on_bit_mean_nm': float(np.mean(series['tob'])),
        'mse_pa': float(kpi.mechanical_specific_energy(
            series['wob'], series['tob'], speed, np.full(n, rop), config.borehole.diameter_m)),
        'oscillation_frequency_hz': oscillation_frequency(speed, dt),
    }


def oscillation_frequency(signal: np.ndarray, dt: float) -> float:
    """
    Frequency (Hz) of a signal from its upward crossings of its mean, interpolated linearly.

    (crossings - 1) / (last - first crossing time); NaN with fewer than two.
    """
    centred = np.asarray(signal, dtype=float) - np.mean(signal)
    up = np.flatnonzero((centred[:-1] < 0) & (centred[1:] >= 0))
    if up.size < 2:
        return math.nan
    times = (up + centred[up] / (centred[up] - centred[up + 1])) * dt
    return float((up.size - 1) / (times[-1] - times[0]))


def run_map(config: DrillStringConfig, spec: MapSpec, executor,
            progress: Callable[[int, int], None] | None = None) -> MapResult:
    """
    Run every point of ``spec`` on ``executor``; progress(done, total) counts points.

    Raises :class:`MapPointError` (before any point runs) for a grid the configuration refuses.
    """
    check_points(config, spec)
    config_json = json.dumps(config_to_dict(config))
    total = spec.shape[0] * spec.shape[1]
    start = time.perf_counter()
    rows = []
    for row in executor.run(run_point, [(config_json, spec, i) for i in range(total)]):
        rows.append(row)
        if progress is not None:
            progress(len(rows), total)
    rows.sort(key=lambda r: r['index'])
    wall = time.perf_counter() - start
    verdicts = compare_with_linear_stability(
        np.array([r['stick_slip_severity'] for r in rows]).reshape(spec.shape),
        np.array([r['linearly_stable'] for r in rows], dtype=bool).reshape(spec.shape),
        np.array([r['failed'] for r in rows], dtype=bool).reshape(spec.shape))
    for row, verdict in zip(rows, verdicts.ravel()):
        row['linear_comparison'] = str(verdict)
    _, system = _system_for(config_json)
    law = BitRockLaw.from_config(config.bit_rock)
    speeds = _fine(spec.speeds_rad_per_s, BOUNDARY_RESOLUTION[0])
    weights = _fine(spec.weights_on_bit_n, BOUNDARY_RESOLUTION[1])
    growth, frequency = stability_grid(system, law, speeds, weights)
    rop = law.steady_rop(speeds[None, :], -weights[:, None])
    return MapResult(spec=spec, config=config, rows=rows, boundary_speeds_rad_per_s=speeds,
                     boundary_weights_on_bit_n=weights, boundary_growth_rate_per_s=growth,
                     boundary_frequency_hz=frequency, boundary_steady_rop_m_per_s=rop,
                     wall_s=wall, workers=getattr(executor, 'workers', 1))


def compare_with_linear_stability(severity: np.ndarray, stable: np.ndarray,
                                  failed: np.ndarray) -> np.ndarray:
    """
    Compare the map with the linear stability boundary, per grid point (n_wob, n_speed).

    'agree' when a linearly stable point is steady (SSI < SSI_STEADY) or an unstable one
    oscillates (SSI >= SSI_STEADY), 'disagree' otherwise, 'near_boundary' when a grid neighbour
    (one step in speed or WOB) is on the other side of the linear stability boundary, 'failed'
    for failed points. Arrays are on the map's grid, both axes increasing (MapSpec sorts them).
    """
    out = np.empty(stable.shape, dtype=object)
    rows, columns = stable.shape
    for i in range(rows):
        for j in range(columns):
            neighbours = [stable[a, b] for a, b in ((i - 1, j), (i + 1, j), (i, j - 1), (i, j + 1))
                          if 0 <= a < rows and 0 <= b < columns]
            if failed[i, j]:
                out[i, j] = 'failed'
            elif any(n != stable[i, j] for n in neighbours):
                out[i, j] = 'near_boundary'
            else:
                steady = severity[i, j] < SSI_STEADY
                out[i, j] = 'agree' if steady == bool(stable[i, j]) else 'disagree'
    return out


def _fine(values, count: int) -> np.ndarray:
    low, high = min(values), max(values)
    return np.array([low]) if high == low else np.linspace(low, high, count)
