"""The twin's engine: the mean model and an online ensemble stepped together, ROS-free.

Member 0 of the batch is the mean model (its germ is the identity, which leaves the bit-rock
law unchanged); members 1..N carry random germs of dispersion delta drawn from the stream
(seed, j). Every ``advance`` steps them all, checks and applies the commands, watches for
borehole impacts and bit lift-offs of the mean model, keeps drilling indicators over a moving
window, and returns a :class:`TwinSnapshot`. A member that diverges is restarted from a safe
state (its depth kept), the step is retried once, and the reset is reported; nothing from a
failed step is returned. If steps keep failing even from the safe state the engine raises
TwinStalled rather than let the twin's clock stand still.
"""
from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from drill_twin.config.schema import DrillStringConfig
from drill_twin.dynamics import kpi
from drill_twin.dynamics.simulator import Observation, SimulationDiverged, Simulator
from drill_twin.uncertainty.germ import germs_for_realizations, validate_dispersion


class CommandRejected(ValueError):
    """A command that is not finite or outside its range; the previous one stays."""


class TwinStalled(RuntimeError):
    """The model failed MAX_CONSECUTIVE_FAILURES steps in a row, even from a safe state: the
    configuration cannot be integrated (the clock would otherwise stand still)."""


MAX_CONSECUTIVE_FAILURES = 100
"""Steps in a row that may fail (each retried once from a safe state) before TwinStalled."""


@dataclass(frozen=True)
class EnsembleSettings:
    """The online ensemble: ``members`` random realizations of dispersion ``dispersion``."""

    members: int = 16
    dispersion: float = 0.01
    seed: int = 0

    def __post_init__(self):
        if self.members < 0:
            raise ValueError(f'ensemble members: must be >= 0, got {self.members}')
        validate_dispersion(self.dispersion)
        if self.seed < 0:
            raise ValueError(f'seed: must be >= 0, got {self.seed}')


@dataclass(frozen=True)
class CommandLimits:
    """Accepted command ranges (rad/s and N)."""

    top_drive_speed_max_rad_per_s: float = 30.0
    hook_load_min_n: float = 0.0
    hook_load_max_n: float = 5.0e6


@dataclass(frozen=True)
class TwinEvent:
    """Something the rig should hear about.

    kind: 'impact' (a node touches the wall), 'contact_end', 'lift_off', 'landing',
    'diverged' (a member was reset), 'command_rejected'. level: 'info', 'warn' or 'error'.
    """

    kind: str
    level: str
    time_s: float
    message: str
    values: dict = field(default_factory=dict)


@dataclass(frozen=True)
class BitState:
    """depth (m), ROP (m/s), WOB (N); angle (rad), speed (rad/s), TOB (N m)."""

    depth_m: float
    rop_m_per_s: float
    weight_on_bit_n: float
    angle_rad: float
    speed_rad_per_s: float
    torque_on_bit_nm: float


@dataclass(frozen=True)
class TwinSnapshot:
    """The twin after a tick (SI units).

    bit: the mean model's bit; ensemble_mean, ensemble_lower (2.5 %), ensemble_upper (97.5 %):
    over the random members (None without an ensemble); observation: the full mean-model
    observation (top, stations, wall); kpis: stick-slip severity (-), MSE (Pa), ROP (m/h)
    over the KPI window; events since the last tick; health: step and timing figures.
    """

    time_s: float
    step: int
    bit: BitState
    ensemble_mean: BitState | None
    ensemble_lower: BitState | None
    ensemble_upper: BitState | None
    observation: Observation
    stick_slip_severity: float
    mse_pa: float
    rop_m_per_h: float
    events: tuple
    health: dict


class TwinEngine:
    """Mean model + online ensemble, stepped in ticks of ``substeps`` model steps.

    Args:
        config: the model.
        ensemble: ensemble size, dispersion and seed.
        limits: accepted command ranges.
        kpi_window_s: moving window of the stick-slip severity and the MSE (s).
        system: a prebuilt reduced system of ``config`` (built if None).
    """

    def __init__(self, config: DrillStringConfig, ensemble: EnsembleSettings = EnsembleSettings(),
                 limits: CommandLimits = CommandLimits(), kpi_window_s: float = 10.0,
                 system=None):
        self.config = config
        self.ensemble = ensemble
        self.limits = limits
        germs = np.eye(2)[None].repeat(1 + ensemble.members, axis=0)
        if ensemble.members:
            germs[1:] = germs_for_realizations(ensemble.dispersion, ensemble.seed,
                                               range(ensemble.members))
        self.simulator = Simulator(config, members=1 + ensemble.members, germs=germs,
                                   system=system)
        self.dt = self.simulator.dt
        self.step_index = 0
        self._window = _RingBuffer(5, 2)
        self.kpi_window_s = float(kpi_window_s)
        self._events = []
        self._consecutive_failures = 0
        self._last = self.simulator.observe()
        self._wall_per_tick = deque(maxlen=100)
        self._iterations = deque(maxlen=100)
        self.resets = 0
        self.rejected_commands = 0

    # -- commands ------------------------------------------------------------------------
    @property
    def top_drive_speed_command(self) -> float:
        return self.simulator.top_speed_command_rad_per_s

    @property
    def hook_load_command(self) -> float:
        return self.simulator.hook_load_command_n

    def set_top_drive_speed(self, rad_per_s: float) -> None:
        """Top-drive speed command (rad/s), applied from the next step; raises CommandRejected."""
        self._check('top-drive speed', rad_per_s, 0.0, self.limits.top_drive_speed_max_rad_per_s,
                    'rad/s')
        self.simulator.set_top_drive_speed(float(rad_per_s))

    def set_hook_load(self, newton: float) -> None:
        """Hook load command (N), applied from the next step; raises CommandRejected."""
        self._check('hook load', newton, self.limits.hook_load_min_n,
                    self.limits.hook_load_max_n, 'N')
        self.simulator.set_hook_load(float(newton))

    def _check(self, what, value, low, high, unit):
        try:
            value = float(value)
        except (TypeError, ValueError):
            value = float('nan')
        reason = None
        if not math.isfinite(value):
            reason = f'{what} command {value} is not a finite number'
        elif not low <= value <= high:
            reason = f'{what} command {value:g} {unit} is outside [{low:g}, {high:g}] {unit}'
        if reason:
            self.rejected_commands += 1
            self._events.append(TwinEvent('command_rejected', 'warn', self.time_s,
                                          reason + '; the previous command stays',
                                          {'command': what, 'value': str(value)}))
            raise CommandRejected(reason)

    # -- stepping ------------------------------------------------------------------------
    @property
    def time_s(self) -> float:
        return self.simulator.time_s

    @property
    def kpi_window_s(self) -> float:
        return self._kpi_window_s

    @kpi_window_s.setter
    def kpi_window_s(self, seconds: float) -> None:
        """The KPI window (s); the ring buffer holds one sample per model step."""
        self._kpi_window_s = float(seconds)
        self._window.resize(int(math.ceil(self._kpi_window_s / self.dt)) + 1)

    def advance(self, steps: int) -> TwinSnapshot:
        """Step the batch ``steps`` times and return the snapshot of the last step."""
        start = time.perf_counter()
        iterations = 0
        for _ in range(steps):
            before = self.simulator.last
            result = self._step_with_retry()
            if result is None:
                continue
            iterations += result.iterations
            self.step_index += 1
            now = self.simulator.last                    # the step's forces: cheap to watch
            self._watch(before, now)
            self._window.append((self.time_s, now.bit_speed_rad_per_s[0], now.rop_m_per_s[0],
                                 now.weight_on_bit_n[0], now.torque_on_bit_nm[0]))
        self._last = self.simulator.observe(detailed=1)        # stations: the mean model's
        self._wall_per_tick.append(time.perf_counter() - start)
        self._iterations.append(iterations / max(steps, 1))
        return self.snapshot()

    def _step_with_retry(self):
        """One step; a failing member is reset and the step retried once."""
        for attempt in range(2):
            try:
                result = self.simulator.step()
                self._consecutive_failures = 0
                return result
            except SimulationDiverged as error:
                self._recover(error)
        self._consecutive_failures += 1
        if self._consecutive_failures >= MAX_CONSECUTIVE_FAILURES:
            raise TwinStalled(f'{MAX_CONSECUTIVE_FAILURES} steps in a row failed, even from a '
                              f'safe state, at t = {self.time_s:.6g} s: the model cannot be '
                              f'integrated with this configuration')
        return None

    def _recover(self, error: SimulationDiverged) -> None:
        members = list(error.members) or list(range(self.simulator.members))
        self.simulator.reset_members(members)
        self.resets += len(members)
        which = 'the mean model' if 0 in members else f'ensemble members {members}'
        self._events.append(TwinEvent(
            'diverged', 'error', self.time_s,
            f'{which} diverged ({error}); restarted from a safe state at the same depth',
            {'members': ' '.join(map(str, members)), 'time_s': f'{error.time_s:.6g}'}))
        self._last = self.simulator.observe()

    def _watch(self, before, now) -> None:
        """Events of the mean model between two steps' force evaluations."""
        x = self.simulator.system.model.mesh.node_x_m
        t = self.time_s
        contact_before, contact_now = before.contact.in_contact[0], now.contact.in_contact[0]
        force = now.contact.radial_force_n[0]
        for node in np.flatnonzero(contact_now & ~contact_before):
            self._events.append(TwinEvent(
                'impact', 'warn', t, f'borehole impact at x = {x[node]:.1f} m, '
                f'force {force[node]:.3g} N',
                {'x_m': f'{x[node]:.3f}', 'force_n': f'{force[node]:.6g}'}))
        for node in np.flatnonzero(contact_before & ~contact_now):
            self._events.append(TwinEvent('contact_end', 'info', t,
                                          f'contact at x = {x[node]:.1f} m ended',
                                          {'x_m': f'{x[node]:.3f}'}))
        if now.lifted[0] and not before.lifted[0]:
            self._events.append(TwinEvent('lift_off', 'warn', t, 'the bit lifted off the rock',
                                          {'rop_m_per_s': f'{now.rop_m_per_s[0]:.6g}'}))
        if before.lifted[0] and not now.lifted[0]:
            self._events.append(TwinEvent('landing', 'info', t, 'the bit is back on the rock'))

    # -- results -------------------------------------------------------------------------
    def kpi_window_samples(self) -> np.ndarray:
        """The mean model's samples inside the KPI window, one per step: columns time (s),
        bit speed (rad/s), ROP (m/s), WOB (N), TOB (N m); shape (n, 5)."""
        window = self._window.values()
        return window[window[:, 0] >= self.time_s - self.kpi_window_s - 1e-9]

    def snapshot(self) -> TwinSnapshot:
        o = self._last
        fields = np.stack([o.depth_m, o.rop_m_per_s, o.weight_on_bit_n, o.angle_rad,
                           o.speed_rad_per_s, o.torque_on_bit_nm], axis=1)     # (members, 6)
        bit = BitState(*map(float, fields[0]))
        mean = lower = upper = None
        if self.ensemble.members:
            ensemble = fields[1:]
            mean = BitState(*map(float, ensemble.mean(axis=0)))
            low, high = _quantiles(ensemble, 0.025, 0.975)
            lower, upper = BitState(*map(float, low)), BitState(*map(float, high))
        window = self.kpi_window_samples()
        if window.shape[0] >= 2:
            ssi = float(kpi.stick_slip_severity(window[:, 1]))
            mse = float(kpi.mechanical_specific_energy(window[:, 3], window[:, 4], window[:, 1],
                                                       window[:, 2],
                                                       self.config.borehole.diameter_m))
            rop = float(np.mean(window[:, 2]))
        else:
            ssi, mse, rop = 0.0, float('nan'), float(o.rop_m_per_s[0])
        events, self._events = tuple(self._events), []
        wall = np.array(self._wall_per_tick) if self._wall_per_tick else np.zeros(1)
        health = {
            'members': self.simulator.members,
            'tick_wall_time_s': float(wall[-1]),
            'tick_wall_time_max_s': float(wall.max()),
            'iterations_per_step': float(np.mean(self._iterations)) if self._iterations else 0.0,
            'resets': self.resets,
            'rejected_commands': self.rejected_commands,
            'ensemble_members_touching_wall': int(o.in_contact[1:].any(axis=1).sum()),
            'ensemble_members_lifted_off': int(o.lifted[1:].sum()),
        }
        return TwinSnapshot(time_s=o.time_s, step=self.step_index, bit=bit, ensemble_mean=mean,
                            ensemble_lower=lower, ensemble_upper=upper, observation=o,
                            stick_slip_severity=ssi, mse_pa=mse, rop_m_per_h=3600.0 * rop,
                            events=events, health=health)


def _quantiles(values: np.ndarray, *probabilities):
    """Quantiles along axis 0 by linear interpolation (numpy's default method), computed
    directly: np.quantile's overhead dominates for a handful of members."""
    ordered = np.sort(values, axis=0)
    last = ordered.shape[0] - 1
    out = []
    for p in probabilities:
        position = p * last
        low = int(np.floor(position))
        high = min(low + 1, last)
        weight = position - low
        out.append(ordered[low] + weight * (ordered[high] - ordered[low]))
    return out


class _RingBuffer:
    """The last ``capacity`` rows of ``width`` floats, in order."""

    def __init__(self, width: int, capacity: int):
        self._data = np.zeros((capacity, width))
        self._count = 0

    def resize(self, capacity: int) -> None:
        kept = self.values()[-capacity:]
        self._data = np.zeros((capacity, self._data.shape[1]))
        self._data[:kept.shape[0]] = kept
        self._count = kept.shape[0]

    def append(self, row) -> None:
        capacity = self._data.shape[0]
        self._data[self._count % capacity] = row
        self._count += 1

    def values(self) -> np.ndarray:
        capacity = self._data.shape[0]
        if self._count <= capacity:
            return self._data[:self._count]
        start = self._count % capacity
        return np.concatenate([self._data[start:], self._data[:start]])
