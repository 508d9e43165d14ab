"""
The twin's engine: the mean model and an online ensemble stepped together, ROS-free.

The mean model (the bit-rock law of the paper's Eq. 25-26) is a batch of one driven by the
rig's machines (:class:`~drill_twin.rig.rig.Rig`); the online ensemble
(:mod:`~drill_twin.twin.ensemble`), N realizations of the random law, is a batch of its own
that follows the mean model's surface motion, in this process or in a worker process. Every
``advance`` steps the mean model under the commands (checked when given,
:mod:`~drill_twin.twin.commands`), hands the tick to the ensemble and collects the previous
tick's ensemble, watches for borehole impacts, landings and bit lift-offs of the mean model
(:mod:`~drill_twin.twin.watch`), keeps drilling indicators over a moving window
(:mod:`~drill_twin.twin.kpi_window`), and returns a :class:`TwinSnapshot`. A member that
diverges is restarted from a safe state (its depth kept), the step is retried once, and the
reset is reported; a member whose step breaks a physical bound
(:mod:`~drill_twin.integrator.guard`) is put back to its last good state and restarted there;
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

import time
from collections import deque
from dataclasses import dataclass

import numpy as np

from drill_twin.assimilation.bounds import interval
from drill_twin.assimilation.sequential import Sample, sample_problem
from drill_twin.config import ConfigError
from drill_twin.config.schema import DrillStringConfig
from drill_twin.integrator.envelope import StringEnvelope
from drill_twin.integrator.simulator import Observation, Simulator
from drill_twin.integrator.stepping import (MAX_CONSECUTIVE_FAILURES, GuardedSimulator, TwinEvent,
                                            TwinStalled)
from drill_twin.rig.drawworks import AxialMode
from drill_twin.rig.rig import Rig
from drill_twin.rig.surface import SurfaceReadings, surface_readings
from drill_twin.twin.commands import CommandInput, CommandLimits, CommandRejected
from drill_twin.twin.ensemble import (BIT_FIELDS, EnsembleFailed, EnsembleResult,
                                      EnsembleSettings, LocalEnsemble, measurement_refused,
                                      open_ensemble, start_worker)
from drill_twin.twin.kpi_window import KpiWindow, quantiles
from drill_twin.twin.watch import EventWatch

__all__ = ['BitState', 'CommandLimits', 'CommandRejected', 'EnsembleSettings', 'TwinEngine',
           'TwinEvent', 'TwinSnapshot', 'TwinStalled', 'MAX_CONSECUTIVE_FAILURES']


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


class TwinEngine(CommandInput):
    """
    Mean model + online ensemble, stepped in ticks of ``substeps`` model steps.

    :param config: the model.
    :param ensemble: ensemble size, dispersion, seed, and whether it runs in a worker process.
    :param limits: accepted command ranges.
    :param kpi_window_s: moving window of the stick-slip severity and the MSE (s).
    :param system: a prebuilt reduced system of ``config`` (built if None).

    ``simulator``: the mean model; ``rig``: its commands and drives. The command methods
    (``set_top_drive_speed``, ``set_hook_load``, ...) are :class:`~drill_twin.twin.commands.
    CommandInput`'s. Call :meth:`close` when done (it stops an ensemble worker process).
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
            self.rig = Rig(self.simulator)
            self.envelope = StringEnvelope.of(self.simulator.system)
            self._mean = GuardedSimulator(self.rig, first_member=0, name='the mean model')
            self._refuse_a_start_the_door_would_refuse(config)
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
        self._kpi = KpiWindow(kpi_window_s, self.dt, config.borehole.diameter_m)
        self._events = []                     # appended to, emptied by snapshot(), never rebound
        self._watch = EventWatch(self.simulator, self._events)
        self._last = self.simulator.observe()
        self._wall_per_tick = deque(maxlen=100)
        self._iterations = deque(maxlen=100)
        self.rejected_commands = 0
        self.commands_received = 0
        self._open_ensemble(worker)
        self._samples: list[Sample] = []
        self._analyses: list = []
        self.measurements_refused = 0
        self.measurements_received = 0

    def _refuse_a_start_the_door_would_refuse(self, config: DrillStringConfig) -> None:
        """Refuse a configured hook load that the command door would refuse, with its reason."""
        if config.operation.hook_load_n is None or self.rig.axial_mode is not AxialMode.HOOK_LOAD:
            return
        reason = self.envelope.hook_load_reason(config.operation.hook_load_n)
        if reason:
            raise ConfigError('configuration', 'operation.hook_load_n', reason)

    def _open_ensemble(self, worker) -> None:
        """Start the ensemble (in its worker if one was started, else in this process)."""
        ensemble, system = self.ensemble, self.simulator.system
        try:
            self.ensemble_runner = open_ensemble(self.config, ensemble, system, worker)
        except EnsembleFailed as error:
            self.ensemble_runner = LocalEnsemble(self.config, ensemble, system)
            self._events.append(TwinEvent(
                'ensemble_failed', 'warn', 0.0,
                f'{error}; the ensemble runs in this process instead'))
        self._ensemble_latest: EnsembleResult | None = (
            self.ensemble_runner.latest if self.ensemble_runner else None)
        self._ensemble_resets = 0

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
        """Sub-step retries of the mean model's simulator so far."""
        return int(self.simulator.retries)

    @property
    def resets(self) -> int:
        """Members restarted from a safe state so far (mean model and ensemble)."""
        return self._mean.resets + self._ensemble_resets

    def close(self) -> None:
        """Stop the ensemble (its worker process, if any)."""
        if self.ensemble_runner is not None:
            self.ensemble_runner.close()
            self.ensemble_runner = None

    # -- stepping ------------------------------------------------------------------------
    @property
    def time_s(self) -> float:
        return self.simulator.time_s

    @property
    def kpi_window_s(self) -> float:
        return self._kpi.window_s

    @kpi_window_s.setter
    def kpi_window_s(self, seconds: float) -> None:
        """Set the KPI window (s); the ring buffer holds one sample per model step."""
        self._kpi.window_s = seconds

    def advance(self, steps: int) -> TwinSnapshot:
        """
        Step the mean model ``steps`` times and return the snapshot of the last step.

        The ensemble is stepped likewise, one tick behind, under the surface motion the mean
        model's drives gave in these steps.
        """
        start = time.perf_counter()
        iterations = 0
        drawworks = self.rig.drawworks
        top_speeds = np.empty(steps)
        block = None if drawworks is None else (np.empty(steps), np.empty(steps))
        for step in range(steps):
            before = self.simulator.last
            result = self._mean.step()
            self._events.extend(self._mean.take_events())
            top_speeds[step] = self.simulator.state.top_speed_rad_per_s
            if block is not None:
                block[0][step] = drawworks.state.block_position_m
                block[1][step] = drawworks.state.block_velocity_m_per_s
            if result is None:
                continue
            iterations += result.iterations
            self.step_index += 1
            now = self.simulator.last                    # the step's forces: cheap to watch
            self._watch.after_step(self.time_s, before, now)
            rop = self.simulator.hole_rop_m_per_s(now.rop_m_per_s)[0]   # the hole's rate
            self._kpi.append(self.time_s, now.bit_speed_rad_per_s[0], rop,
                             now.weight_on_bit_n[0], now.torque_on_bit_nm[0])
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

    # -- results -------------------------------------------------------------------------
    def kpi_window_samples(self) -> np.ndarray:
        """
        Return the mean model's samples inside the KPI window, one per step.

        Columns time (s), bit speed (rad/s), ROP (m/s), WOB (N), TOB (N m); shape (n, 5).
        """
        return self._kpi.samples(self.time_s)

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
                low, high = quantiles(ensemble.bit, 0.025, 0.975)
            mean = BitState(*map(float, centre))
            lower, upper = BitState(*map(float, low)), BitState(*map(float, high))
            ensemble_step, ensemble_time = ensemble.step, ensemble.time_s
        ssi, mse, rop = self._kpi.kpis(self.time_s)
        events = tuple(self._events)
        self._events.clear()
        analyses, self._analyses = tuple(self._analyses), []
        return TwinSnapshot(time_s=o.time_s, step=self.step_index, bit=bit, ensemble_mean=mean,
                            ensemble_lower=lower, ensemble_upper=upper,
                            ensemble_step=ensemble_step, ensemble_time_s=ensemble_time,
                            observation=o, stick_slip_severity=ssi, mse_pa=mse,
                            rop_m_per_h=rop, events=events, health=self._health(ensemble),
                            surface=surface_readings(self.rig, o, self.envelope.string_weight_n),
                            analyses=analyses)

    def _health(self, ensemble: EnsembleResult | None) -> dict:
        """Return the step, timing and failure counters of the snapshot."""
        wall = np.array(self._wall_per_tick) if self._wall_per_tick else np.zeros(1)
        guarded = self._mean
        return {
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
