"""
The twin's engine: the mean model and an online ensemble stepped together, ROS-free.

The mean model (the bit-rock law of the paper's Eq. 25-26) is a batch of one; the online
ensemble (:mod:`~drill_twin.twin.ensemble`), N realizations of the random law, is a batch of
its own, stepped under the same commands in this process or in a worker process. Every
``advance`` checks and applies the commands, steps the mean model, hands the tick to the
ensemble and collects the previous tick's ensemble, watches for borehole impacts and bit
lift-offs of the mean model, keeps drilling indicators over a moving window, and returns a
:class:`TwinSnapshot`. A member that diverges is restarted from a safe state (its depth kept),
the step is retried once, and the reset is reported; a member whose step breaks a physical
bound (:mod:`~drill_twin.integrator.guard`) is put back to its last good state and restarted there;
nothing from a failed or implausible step is returned. Commands are accepted only inside the
range the model can represent (:mod:`~drill_twin.integrator.envelope`), within the
operator's limits.
A configuration whose initial state already breaks a bound is refused (ConfigError).
If the mean model keeps failing even from the safe state the engine raises TwinStalled rather
than let the twin's clock stand still; an ensemble worker that cannot start is replaced by an
in-process ensemble (a warning event), one that fails later is dropped with an error event
and the mean model goes on. The mean model does not depend on the ensemble: the same commands
give the same mean model with any ensemble, or none.
"""
from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass

import numpy as np

from drill_twin.assimilation.bounds import interval
from drill_twin.assimilation.sequential import Sample, sample_problem
from drill_twin.config import ConfigError
from drill_twin.config.schema import DrillStringConfig
from drill_twin.analysis import kpi
from drill_twin.rig import drives as rig
from drill_twin.integrator.simulator import Observation, Simulator
from drill_twin.twin.ensemble import (BIT_FIELDS, EnsembleFailed, EnsembleResult,
                                      EnsembleSettings, LocalEnsemble, measurement_refused,
                                      open_ensemble, start_worker)
from drill_twin.integrator.envelope import StringEnvelope
from drill_twin.integrator.stepping import (MAX_CONSECUTIVE_FAILURES, GuardedSimulator, TwinEvent,
                                            TwinStalled)
from drill_twin.rig.surface import SurfaceReadings, surface_readings

__all__ = ['BitState', 'CommandLimits', 'CommandRejected', 'EnsembleSettings', 'TwinEngine',
           'TwinEvent', 'TwinSnapshot', 'TwinStalled', 'MAX_CONSECUTIVE_FAILURES']


LANDING_PEAK_WINDOW_S = 1.0
"""Longest wait for a landing's peak WOB (s): a bit set down slowly, whose WOB keeps rising,
is reported with the WOB reached by then."""


class CommandRejected(ValueError):
    """A command that is not finite or outside its range; the previous one stays."""


@dataclass(frozen=True)
class CommandLimits:
    """
    The operator's command ranges (rad/s and N).

    A clamp on top of what the model can represent (the hook load's range derived from the
    string, :mod:`.envelope`).
    """

    top_drive_speed_max_rad_per_s: float = 30.0
    hook_load_min_n: float = 0.0
    hook_load_max_n: float = 5.0e6
    top_drive_torque_limit_max_nm: float = 500.0e3


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
    """
    The twin after a tick (SI units).

    bit: the mean model's bit; ensemble_mean, ensemble_lower (2.5 %), ensemble_upper (97.5 %):
    over the random members, at the ensemble's own step ``ensemble_step`` and time
    ``ensemble_time_s``, one tick behind the mean model (all None without an ensemble);
    observation: the full mean-model observation (top, stations, wall); kpis: stick-slip
    severity (-), MSE (Pa), ROP (m/h) over the KPI window, each None when it cannot be
    computed (no window yet, the bit not turning forwards or not advancing on average, or a
    non-finite value): never a substitute number; events since the last tick; health: step,
    timing and failure counters. With assimilation the ensemble is the filter's analysed
    ensemble, its bounds drawn as the filter's settings say (``filter.bounds``), and
    ``analyses`` holds the analyses the ensemble made since the last snapshot
    (:class:`~drill_twin.assimilation.sequential.AnalysisRecord`).
    """

    time_s: float
    step: int
    bit: BitState
    ensemble_mean: BitState | None
    ensemble_lower: BitState | None
    ensemble_upper: BitState | None
    ensemble_step: int | None
    ensemble_time_s: float | None
    observation: Observation
    stick_slip_severity: float | None
    mse_pa: float | None
    rop_m_per_h: float | None
    events: tuple
    health: dict
    surface: SurfaceReadings | None = None
    analyses: tuple = ()


class TwinEngine:
    """
    Mean model + online ensemble, stepped in ticks of ``substeps`` model steps.

    :param config: the model.
    :param ensemble: ensemble size, dispersion, seed, and whether it runs in a worker process.
    :param limits: accepted command ranges.
    :param kpi_window_s: moving window of the stick-slip severity and the MSE (s).
    :param system: a prebuilt reduced system of ``config`` (built if None).

    Call :meth:`close` when done (it stops an ensemble worker process).
    """

    def __init__(self, config: DrillStringConfig, ensemble: EnsembleSettings = EnsembleSettings(),
                 limits: CommandLimits = CommandLimits(), kpi_window_s: float = 10.0,
                 system=None):
        self.config = config
        self.ensemble = ensemble
        self.limits = limits
        worker = start_worker(ensemble)         # its start-up runs while the mean model builds
        try:
            self.simulator = Simulator(config, members=1, system=system)
            self.envelope = StringEnvelope.of(self.simulator.system)
            self._mean = GuardedSimulator(self.simulator, first_member=0,
                                          name='the mean model')
            initial = self._mean.guard.check(self.simulator)
            if initial:
                raise ConfigError('configuration', '', f'the model cannot be integrated: at '
                                  f't = 0 {initial[0]}')
        except BaseException:
            if worker is not None:
                worker.close()
            raise
        self.dt = self.simulator.dt
        self.step_index = 0
        self._window = _RingBuffer(5, 2)
        self.kpi_window_s = float(kpi_window_s)
        self._events = []
        self._last = self.simulator.observe()
        self._on_bottom = bool(self.simulator.on_bottom()[0])
        self._landing = None                  # a landing whose peak WOB is still to come
        self._wall_per_tick = deque(maxlen=100)
        self._iterations = deque(maxlen=100)
        self.rejected_commands = 0
        self.commands_received = 0
        self._controller = config.top_drive.controller
        self._torque_limit_nm = None
        self._block_velocity = None
        self._weight_on_bit_setpoint = None
        try:
            self.ensemble_runner = open_ensemble(config, ensemble, self.simulator.system,
                                                 worker)
        except EnsembleFailed as error:
            self.ensemble_runner = LocalEnsemble(config, ensemble, self.simulator.system)
            self._events.append(TwinEvent(
                'ensemble_failed', 'warn', 0.0,
                f'{error}; the ensemble runs in this process instead'))
        self._ensemble_latest: EnsembleResult | None = (
            self.ensemble_runner.latest if self.ensemble_runner else None)
        self._ensemble_resets = 0
        self._samples: list[Sample] = []
        self._analyses: list = []
        self.measurements_refused = 0
        self.measurements_received = 0

    @property
    def assimilating(self) -> bool:
        """Whether the ensemble is an ensemble Kalman filter's (it has assimilation settings)."""
        return self.ensemble.assimilation is not None and self.ensemble_runner is not None

    def offer_measurement(self, sample: Sample) -> str | None:
        """
        Hand a rig measurement sample to the ensemble filter (with the next tick's work).

        Return why it is refused (one phrase; a 'measurement_rejected' event, counted), or
        None. The stamp is in model time (s).
        """
        self.measurements_received += 1
        problem = sample_problem(sample)
        if problem is None and not self.assimilating:
            problem = 'the twin does not assimilate (no ensemble filter)'
        if problem is not None:
            self.refuse_measurement(problem)
            return problem
        self._samples.append(sample)
        return None

    def refuse_measurement(self, problem: str) -> None:
        """Count a measurement refused before it became a sample (e.g. a malformed message)."""
        self.measurements_refused += 1
        self._events.append(measurement_refused(self.time_s, problem))

    @property
    def retries(self) -> int:
        """Sub-step retries of the mean model's simulator so far (0 if it has none)."""
        return int(getattr(self.simulator, 'retries', 0))

    @property
    def resets(self) -> int:
        """Members restarted from a safe state so far (mean model and ensemble)."""
        return self._mean.resets + self._ensemble_resets

    def close(self) -> None:
        """Stop the ensemble (its worker process, if any)."""
        if self.ensemble_runner is not None:
            self.ensemble_runner.close()
            self.ensemble_runner = None

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
        """
        Set the hook load command (N), applied from the next step; raises CommandRejected.

        Accepted inside the operator's limits and the range the model can represent (the
        string's weight minus the largest WOB up to the weight plus the drag of a string
        rising at block speed, :class:`~drill_twin.integrator.envelope.StringEnvelope`).
        """
        self._check('hook load', newton, self.limits.hook_load_min_n,
                    self.limits.hook_load_max_n, 'N', self._hook_load_reason)
        self.simulator.set_hook_load(float(newton))

    def _hook_load_reason(self, newton: float) -> str | None:
        if rig.drawworks_of(self.simulator) is not None:
            return (f'the hook load is what the drill line pulls in axial mode '
                    f'{self.axial_mode} (switch the axial mode to hook_load first)')
        return self.envelope.hook_load_reason(newton)

    # The rig's drives (issue 13, docs/DRIVES.md): the mean model's simulator takes them; the
    # ensemble turns at the mean model's top speed and, axially, takes the hook load the mean
    # model applies or, with the drawworks, hangs every member's line from the mean model's
    # block (``_exchange_with_ensemble``).
    def set_top_drive_mode(self, mode: str) -> None:
        """Switch the top drive, 'kinematic' or 'dynamic' (bumpless); raises CommandRejected."""
        self._check_choice('top-drive mode', mode, ('kinematic', 'dynamic'))
        rig.set_top_drive_mode(self.simulator, mode, self._controller)
        self._apply_torque_limit()

    def set_top_drive_controller(self, controller: str) -> None:
        """
        Set the dynamic drive's controller: 'stiff', 'soft_torque' or 'impedance'.

        Kept for when the drive becomes dynamic; raises CommandRejected.
        """
        self._check_choice('top-drive controller', controller,
                           ('stiff', 'soft_torque', 'impedance'))
        self._controller = controller
        if self.top_drive_mode == 'dynamic':
            rig.set_top_drive_mode(self.simulator, 'dynamic', controller)
            self._apply_torque_limit()

    def set_top_drive_torque_limit(self, newton_metre: float) -> None:
        """
        Set the dynamic drive's motor torque limit (N m, > 0).

        Kept for when the drive becomes dynamic; raises CommandRejected.
        """
        self._check('top-drive torque limit', newton_metre, 0.0,
                    self.limits.top_drive_torque_limit_max_nm, 'N m',
                    lambda v: None if v > 0 else (f'top-drive torque limit command {v:g} N m '
                                                  f'must be > 0 N m'))
        self._torque_limit_nm = float(newton_metre)
        self._apply_torque_limit()

    def set_axial_mode(self, mode: str) -> None:
        """Switch the axial input (hook_load, block_velocity, autodriller; bumpless)."""
        self._check_choice('axial mode', mode, ('hook_load', 'block_velocity', 'autodriller'))
        fresh = rig.drawworks_of(self.simulator) is None
        rig.set_axial_mode(self.simulator, mode)
        drawworks = rig.drawworks_of(self.simulator)
        if fresh and drawworks is not None:          # the set-points sent before the switch
            if self._block_velocity is not None:
                drawworks.set_block_velocity(self._block_velocity)
            if self._weight_on_bit_setpoint is not None:
                drawworks.set_weight_on_bit_setpoint(self._weight_on_bit_setpoint)

    def set_block_velocity(self, m_per_s: float) -> None:
        """Set the block velocity (m/s, down > 0) block_velocity mode follows."""
        from drill_twin.integrator.envelope import PLAUSIBLE_BLOCK_SPEED_M_PER_S as fastest
        self._check('block velocity', m_per_s, -fastest, fastest, 'm/s')
        self._block_velocity = float(m_per_s)
        if (drawworks := rig.drawworks_of(self.simulator)) is not None:
            drawworks.set_block_velocity(self._block_velocity)

    def set_weight_on_bit_setpoint(self, newton: float) -> None:
        """Set the autodriller's WOB set-point (N, compression > 0, up to the envelope's)."""
        self._check('WOB set-point', newton, 0.0, self.envelope.weight_on_bit_max_n, 'N')
        self._weight_on_bit_setpoint = float(newton)
        if (drawworks := rig.drawworks_of(self.simulator)) is not None:
            drawworks.set_weight_on_bit_setpoint(self._weight_on_bit_setpoint)

    @property
    def top_drive_mode(self) -> str:
        """Return 'dynamic' or 'kinematic': the mean model's top drive now."""
        return 'dynamic' if hasattr(rig.top_drive_of(self.simulator), 'loop') else 'kinematic'

    @property
    def top_drive_controller(self) -> str:
        """Return the dynamic drive's controller (kept while the drive is kinematic)."""
        return self._controller

    @property
    def axial_mode(self) -> str:
        """Return the mean model's axial input now (hook_load, block_velocity, autodriller)."""
        drawworks = rig.drawworks_of(self.simulator)
        return 'hook_load' if drawworks is None else drawworks.mode

    def _apply_torque_limit(self) -> None:
        if self._torque_limit_nm is not None and self.top_drive_mode == 'dynamic':
            rig.set_torque_limit(self.simulator, self._torque_limit_nm)

    def _check_choice(self, what: str, value, choices) -> None:
        self.commands_received += 1
        if value not in choices:
            reason = f'{what} command {value!r} is not one of {", ".join(choices)}'
            self.rejected_commands += 1
            self._events.append(TwinEvent('command_rejected', 'warn', self.time_s,
                                          reason + '; the previous command stays',
                                          {'command': what, 'value': str(value)}))
            raise CommandRejected(reason)

    def _check(self, what, value, low, high, unit, physics=None):
        self.commands_received += 1
        try:
            value = float(value)
        except (TypeError, ValueError):
            value = float('nan')
        reason = None
        if not math.isfinite(value):
            reason = f'{what} command {value} is not a finite number'
        elif not low <= value <= high:
            reason = f'{what} command {value:g} {unit} is outside [{low:g}, {high:g}] {unit}'
        elif physics is not None:
            reason = physics(value)
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
        """Set the KPI window (s); the ring buffer holds one sample per model step."""
        self._kpi_window_s = float(seconds)
        self._window.resize(int(math.ceil(self._kpi_window_s / self.dt)) + 1)

    def advance(self, steps: int) -> TwinSnapshot:
        """
        Step the mean model ``steps`` times and return the snapshot of the last step.

        The ensemble is stepped likewise, one tick behind, under the surface motion the mean
        model's drives gave in these steps.
        """
        start = time.perf_counter()
        iterations = 0
        drawworks = rig.drawworks_of(self.simulator)
        top_speeds = np.empty(steps)
        block = None if drawworks is None else (np.empty(steps), np.empty(steps))
        for step in range(steps):
            before = self.simulator.last
            result = self._mean.step()
            self._events.extend(self._mean.take_events())
            top_speeds[step] = self.simulator.state.top_speed_rad_per_s
            if block is not None:
                block[0][step] = drawworks.block_position_m
                block[1][step] = drawworks.block_velocity_m_per_s
            if result is None:
                continue
            iterations += result.iterations
            self.step_index += 1
            now = self.simulator.last                    # the step's forces: cheap to watch
            self._watch(before, now)
            rop = self.simulator.hole_rop_m_per_s(now.rop_m_per_s)[0]   # the hole's rate
            self._window.append((self.time_s, now.bit_speed_rad_per_s[0], rop,
                                 now.weight_on_bit_n[0], now.torque_on_bit_nm[0]))
        self._exchange_with_ensemble(steps, top_speeds, block)
        self._last = self.simulator.observe()
        self._wall_per_tick.append(time.perf_counter() - start)
        self._iterations.append(iterations / max(steps, 1))
        return self.snapshot()

    def _exchange_with_ensemble(self, steps: int, top_speeds, block) -> None:
        """
        Collect the ensemble's previous tick and hand it this one.

        This tick's work: the mean model's top speeds and block (positions, velocities) at the
        end of each of its steps (None under the hook load command).
        """
        if self.ensemble_runner is None:
            return
        samples, self._samples = tuple(self._samples), []
        try:
            latest = self.ensemble_runner.collect()
            self.ensemble_runner.start(steps, top_speeds, self.hook_load_command, block, samples)
        except (EnsembleFailed, TwinStalled) as error:
            self.ensemble_runner.close()
            self.ensemble_runner, self._ensemble_latest = None, None
            self._events.append(TwinEvent(
                'ensemble_failed', 'error', self.time_s,
                f'{error}; the ensemble is dropped and the mean model goes on'))
            return
        if latest is not self._ensemble_latest:
            self._events.extend(latest.events)
            self._ensemble_resets = latest.resets
            self._analyses.extend(latest.analyses)
        self._ensemble_latest = latest

    def _watch(self, before, now) -> None:
        """
        Events of the mean model between two steps' force evaluations.

        Landing: one 'landing' per touch-down of the bit on the hole bottom, stamped at the
        touch-down with the bit's axial speed just before it and the impact's peak WOB (the
        first maximum of the WOB after it, within LANDING_PEAK_WINDOW_S; on the rock's spring
        it comes some 70 ms after the touch-down), sent when that peak has passed.
        Wall contact: one 'impact' per contact episode of a node (it opens when the node
        penetrates the wall; dynamics/contact_events.py), with the node's depth and the force
        of its first step, and one 'contact_end' when the episode closes (the node is more
        than the hysteresis away from the wall), with the episode's peak force, peak
        penetration and duration: a node rubbing or chattering on the wall is one event.
        """
        t = self.time_s
        episodes = self.simulator.contact_episodes
        force = now.contact.radial_force_n[0]
        for event in (e for e in episodes.opened if e.member == 0):
            self._events.append(TwinEvent(
                'impact', 'warn', t, f'borehole impact at x = {event.depth_m:.1f} m, '
                f'force {force[event.node]:.3g} N',
                {'x_m': f'{event.depth_m:.3f}', 'force_n': f'{force[event.node]:.6g}'}))
        for event in (e for e in episodes.closed if e.member == 0):
            duration = event.end_s - event.start_s
            self._events.append(TwinEvent(
                'contact_end', 'info', t, f'contact at x = {event.depth_m:.1f} m ended after '
                f'{duration:.3g} s, peak force {event.peak_force_n:.3g} N',
                {'x_m': f'{event.depth_m:.3f}', 'peak_force_n': f'{event.peak_force_n:.6g}',
                 'peak_penetration_m': f'{event.peak_penetration_m:.6g}',
                 'duration_s': f'{duration:.6g}'}))
        on_bottom = bool(self.simulator.on_bottom()[0])
        landing = self._landing
        if landing is not None:
            compression = -float(now.weight_on_bit_n[0])
            rising = on_bottom and compression >= landing['peak_n']
            if rising:
                landing.update(peak_n=compression, peak_s=t)
            if not rising or t - landing['time_s'] >= LANDING_PEAK_WINDOW_S:
                self._report_landing()
        if on_bottom != self._on_bottom:
            hole = float(self.simulator.hole_depth_m[0])
            if on_bottom:           # an axial impact on the rock: reported at its peak force
                self._landing = {'time_s': t, 'hole_m': hole,
                                 'speed_m_per_s': float(before.rop_m_per_s[0]),
                                 'peak_n': -float(now.weight_on_bit_n[0]), 'peak_s': t}
            else:
                self._events.append(TwinEvent(
                    'lift_off', 'warn', t, f'the bit lifted off bottom at {hole:.2f} m',
                    {'hole_depth_m': f'{hole:.3f}',
                     'speed_m_per_s': f'{now.rop_m_per_s[0]:.6g}'}))
            self._on_bottom = on_bottom

    def _report_landing(self) -> None:
        """Report the pending landing: its time, the bit's speed before, the impact's peak WOB."""
        landing, self._landing = self._landing, None
        peak_kn = landing['peak_n'] / 1e3
        self._events.append(TwinEvent(
            'landing', 'warn', landing['time_s'],
            f'the bit landed on bottom at {landing["hole_m"]:.2f} m '
            f'({landing["speed_m_per_s"]:.3g} m/s, peak weight on bit {peak_kn:.3g} kN '
            f'{landing["peak_s"] - landing["time_s"]:.3g} s later)',
            {'hole_depth_m': f'{landing["hole_m"]:.3f}',
             'speed_m_per_s': f'{landing["speed_m_per_s"]:.6g}',
             'peak_weight_on_bit_n': f'{landing["peak_n"]:.6g}',
             'time_to_peak_s': f'{landing["peak_s"] - landing["time_s"]:.6g}'}))

    # -- results -------------------------------------------------------------------------
    def kpi_window_samples(self) -> np.ndarray:
        """
        Return the mean model's samples inside the KPI window, one per step.

        Columns time (s), bit speed (rad/s), ROP (m/s), WOB (N), TOB (N m); shape (n, 5).
        """
        window = self._window.values()
        return window[self._in_window(window[:, 0])]

    def _in_window(self, times_s: np.ndarray) -> np.ndarray:
        """Which of the samples taken at ``times_s`` are inside the KPI window, (n,) bools."""
        return times_s >= self._window_start_s()

    def _window_start_s(self) -> float:
        """Return the time of the KPI window's start (s): the samples at or after it are in."""
        return self.time_s - self.kpi_window_s - 1e-9

    def snapshot(self) -> TwinSnapshot:
        o = self._last
        bit = BitState(*(float(getattr(o, name)[0]) for name in BIT_FIELDS))
        mean = lower = upper = ensemble_step = ensemble_time = None
        ensemble = self._ensemble_latest
        if ensemble is not None:
            if self.ensemble.assimilation is not None:
                centre, low, high = interval(ensemble.bit,
                                             self.ensemble.assimilation.filter.bounds)
            else:
                centre = ensemble.bit.mean(axis=0)
                low, high = _quantiles(ensemble.bit, 0.025, 0.975)
            mean = BitState(*map(float, centre))
            lower, upper = BitState(*map(float, low)), BitState(*map(float, high))
            ensemble_step, ensemble_time = ensemble.step, ensemble.time_s
        ssi, mse, rop = self._kpis()
        events, self._events = tuple(self._events), []
        analyses, self._analyses = tuple(self._analyses), []
        wall = np.array(self._wall_per_tick) if self._wall_per_tick else np.zeros(1)
        guarded = self._mean
        health = {
            'members': 1 + (self.ensemble.members if ensemble is not None else 0),
            'tick_wall_time_s': float(wall[-1]),
            'tick_wall_time_max_s': float(wall.max()),
            'iterations_per_step': float(np.mean(self._iterations)) if self._iterations else 0.0,
            'ensemble_iterations_per_step': ensemble.iterations_per_step if ensemble else 0.0,
            'ensemble_tick_wall_time_s': ensemble.wall_s if ensemble else 0.0,
            'resets': self.resets,
            'mean_model_resets': guarded.resets,
            'mean_model_failed_steps': guarded.failed_steps,
            'mean_model_implausible_steps': guarded.breaches,
            'mean_model_diverged': guarded.resets - guarded.breaches,
            'ensemble_resets': self._ensemble_resets,
            'retries': self.retries,
            'rejected_commands': self.rejected_commands,
            'commands_received': self.commands_received,
            'ensemble_members_touching_wall': ensemble.touching_wall if ensemble else 0,
            'ensemble_members_lifted_off': ensemble.lifted_off if ensemble else 0,
            'measurements_received': self.measurements_received,
            'measurements_refused': (self.measurements_refused
                                     + (ensemble.samples_refused if ensemble else 0)),
            'measurements_used': ensemble.samples_used if ensemble else 0,
        }
        return TwinSnapshot(time_s=o.time_s, step=self.step_index, bit=bit, ensemble_mean=mean,
                            ensemble_lower=lower, ensemble_upper=upper,
                            ensemble_step=ensemble_step, ensemble_time_s=ensemble_time,
                            observation=o, stick_slip_severity=ssi, mse_pa=mse,
                            rop_m_per_h=rop, events=events, health=health,
                            surface=surface_readings(self.simulator, o,
                                                     self.envelope.string_weight_n),
                            analyses=analyses)

    def _kpis(self) -> tuple[float | None, float | None, float | None]:
        """
        (stick-slip severity, MSE in Pa, ROP in m/h) over the KPI window.

        None where a value cannot be computed (fewer than two samples, non-finite).
        """
        times, speed, rop, wob, tob = self._window.stored()   # (in any order)
        count, speed, fastest, slowest, rop, wob, power = kpi.window_means(
            times, self._window_start_s(), speed, rop, wob, tob)
        if count < 2:
            return None, None, None
        ssi = kpi.severity_of(speed, fastest, slowest)
        mse = kpi.specific_energy_of(wob, power, rop, self.config.borehole.diameter_m)
        rop = 3600.0 * rop
        return tuple(float(v) if np.isfinite(v) else None for v in (ssi, mse, rop))


def _quantiles(values: np.ndarray, *probabilities):
    """
    Quantiles along axis 0 by linear interpolation (numpy's default method), computed directly.

    np.quantile's overhead dominates for a handful of members.
    """
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
    """
    The last ``capacity`` rows of ``width`` floats.

    Stored by column, each contiguous: the KPIs reduce the columns of the whole window at
    every tick (:meth:`stored`, in storage order: means and extremes do not need time order),
    which on rows in time order cost a copy of the window and strided reductions (2001 rows
    of 5: 110-160 us a tick against 70-100, the rest numpy's cost per call, measured).
    """

    def __init__(self, width: int, capacity: int):
        self._data = np.zeros((width, capacity))
        self._count = 0

    def resize(self, capacity: int) -> None:
        kept = self.values()[-capacity:]
        self._data = np.zeros((self._data.shape[0], capacity))
        self._data[:, :kept.shape[0]] = kept.T
        self._count = kept.shape[0]

    def append(self, row) -> None:
        capacity = self._data.shape[1]
        self._data[:, self._count % capacity] = row
        self._count += 1

    def values(self) -> np.ndarray:
        """Return the rows in time order, (n, width) (a copy)."""
        capacity = self._data.shape[1]
        if self._count <= capacity:
            return self._data[:, :self._count].T.copy()
        start = self._count % capacity
        return np.concatenate([self._data[:, start:], self._data[:, :start]], axis=1).T

    def stored(self) -> np.ndarray:
        """Return the columns as stored, (width, n): each row once, not in time order (a view)."""
        return self._data[:, :min(self._count, self._data.shape[1])]
