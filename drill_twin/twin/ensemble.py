"""
The twin's online ensemble.

N realizations of the random bit-rock law, stepped as a batch beside the mean model, in this
process or in a worker process of its own.

The engine hands the ensemble each tick's work with :meth:`start` once the mean model has
taken the tick's steps, with what the rig applied at the surface in each of them (the top
speed, the block's position and velocity or the hook load), and picks the result up with
:meth:`collect` at the end of the next tick, so that a worker process integrates the ensemble
while the node steps the mean model and publishes: the two cores of a small machine share the
load, and the ensemble's statistics lag the mean model by one tick (each result carries its
own step and time). The members follow the rig's drives (they turn at the mean model's top
speed and hang from its block) rather than simulating drives of their own: a twin's members
see the surface motion the rig measures. Both kinds compute the same numbers: the worker
receives the reduced system built here.

Member j (1..N) carries the germ of realization j - 1 of the stream ``seed``
(:func:`~drill_twin.uncertainty.germ.germs_for_realizations`).

With ``assimilation`` settings the ensemble is an ensemble Kalman filter's
(:class:`~drill_twin.assimilation.sequential.SequentialFilter`, docs/ASSIMILATION.md): the rig's
measurement samples handed over with a tick's work are analysed as the members' time reaches
their stamps, the members' state and germs corrected; each result carries the tick's analyses.
"""
from __future__ import annotations

import multiprocessing.connection
import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from drill_twin.assimilation.sequential import AnalysisRecord, Sample, SequentialFilter
from drill_twin.assimilation.settings import AssimilationConfig
from drill_twin.assimilation.state import law_scales_for_members
from drill_twin.config.schema import DrillStringConfig
from drill_twin.integrator.simulator import Simulator
from drill_twin.integrator.stepping import GuardedSimulator, TwinEvent
from drill_twin.rig.drawworks import AxialMode
from drill_twin.rig.rig import Rig
from drill_twin.rig.top_drive import TopDriveMode
from drill_twin.uncertainty.executors import SINGLE_THREADED_BLAS
from drill_twin.uncertainty.germ import germs_for_realizations, validate_dispersion

BIT_FIELDS = ('depth_m', 'rop_m_per_s', 'weight_on_bit_n', 'angle_rad', 'speed_rad_per_s',
              'torque_on_bit_nm')
"""The columns of :attr:`EnsembleResult.bit`, in the order of BitState's fields."""

WORKER_START_TIMEOUT_S = 120.0
"""How long a worker process may take to import and start (s)."""

WORKER_MODULE = 'drill_twin.twin.ensemble_worker'
"""What the worker process runs (``python -m WORKER_MODULE FD``)."""

WORKER_REPLY_TIMEOUT_S = 60.0
"""How long a worker process may take over one tick before it is taken for lost (s)."""


@dataclass(frozen=True)
class EnsembleSettings:
    """
    The online ensemble.

    ``members`` random realizations of dispersion ``dispersion`` drawn from the stream ``seed``;
    ``separate_process``: integrate them in a worker process (a second core) instead of this
    one; ``assimilation``: the ensemble filter's settings (None: open loop; the filter's
    Generator is spawned from ``seed``).
    """

    members: int = 16
    dispersion: float = 0.01
    seed: int = 0
    separate_process: bool = False
    assimilation: AssimilationConfig | None = None

    def __post_init__(self):
        if self.members < 0:
            raise ValueError(f'ensemble members: must be >= 0, got {self.members}')
        if self.assimilation is not None and self.members < 2:
            raise ValueError(f'ensemble members: assimilation needs >= 2, got {self.members}')
        validate_dispersion(self.dispersion)
        if self.seed < 0:
            raise ValueError(f'seed: must be >= 0, got {self.seed}')


class EnsembleFailed(RuntimeError):
    """The ensemble cannot go on (its worker process ended or its model stalled)."""


@dataclass(frozen=True)
class EnsembleResult:
    """
    The ensemble after a tick.

    step: model steps taken; time_s: its time (s); bit: shape (N, 6), columns BIT_FIELDS (SI);
    touching_wall, lifted_off: how many members touch the borehole wall or have their bit
    off the rock; events: restarts of diverged members, refused measurement samples; resets:
    members restarted so far; iterations_per_step: of the tick; wall_s: the wall time the
    tick's steps took (s); analyses: the ensemble filter's analyses of the tick (empty in
    open loop); samples_used, samples_refused: the filter's counts so far.
    """

    step: int
    time_s: float
    bit: np.ndarray
    touching_wall: int
    lifted_off: int
    events: tuple[TwinEvent, ...]
    resets: int
    iterations_per_step: float
    wall_s: float = 0.0
    analyses: tuple[AnalysisRecord, ...] = ()
    samples_used: int = 0
    samples_refused: int = 0


class RedrawnMembers:
    """
    Fresh draws of the prior for the open-loop members the batch cannot integrate.

    A member that breaks a physical bound in MAX_CONSECUTIVE_FAILURES steps in a row, even
    from a safe state, has a germ the model cannot integrate under these commands. Rather than
    drop the whole ensemble (and its bounds), such a member takes the state of a healthy
    member drawn at random and the germ of the next realization of the same study
    (realizations N, N + 1, ... of the ensemble's seed and dispersion: reproducible), so the
    ensemble goes on sampling the prior among the germs the model can integrate. A copy of
    another member's germ (what the filter does) would instead shrink the envelope.
    """

    def __init__(self, settings: EnsembleSettings):
        self.dispersion, self.seed = settings.dispersion, settings.seed
        self.next_realization = settings.members
        self._donors = np.random.default_rng(np.random.SeedSequence(settings.seed,
                                                                    spawn_key=(2,)))

    def choose(self, stalled, members: int) -> tuple[dict[int, int], np.ndarray | None]:
        """Return {member: donor} and the new germs (k, 2, 2) in the members' order."""
        stalled = sorted(set(int(m) for m in stalled))
        healthy = [m for m in range(members) if m not in stalled]
        if not stalled or not healthy:
            return {}, None
        replaced = {m: int(self._donors.choice(healthy)) for m in stalled}
        first = self.next_realization
        self.next_realization += len(stalled)
        return replaced, germs_for_realizations(self.dispersion, self.seed,
                                                range(first, self.next_realization))


class LocalEnsemble:
    """The ensemble integrated in this process (``collect`` does the work)."""

    def __init__(self, config: DrillStringConfig, settings: EnsembleSettings, system):
        germs = germs_for_realizations(settings.dispersion, settings.seed,
                                       range(settings.members))
        spec = None if settings.assimilation is None else settings.assimilation.filter
        scales = (law_scales_for_members(spec.law_prior_log_std, spec.seed, settings.members)
                  if spec is not None and spec.parameters == 'law' else None)
        simulator = Simulator(config, members=settings.members, germs=germs, system=system,
                              law_scales=scales)
        # The members turn with the rig's top and hang from its block (or its hook load).
        self.rig = Rig(simulator)
        self.rig.set_top_drive_mode(TopDriveMode.FOLLOWED)
        self.rig.set_axial_mode(AxialMode.HOOK_LOAD)
        self.guarded = GuardedSimulator(self.rig, first_member=1, name='ensemble members')
        self.filter = None
        if settings.assimilation is not None:
            rng = np.random.default_rng(np.random.SeedSequence(settings.seed, spawn_key=(1,)))
            self.filter = SequentialFilter(simulator, settings.members, settings.assimilation,
                                           rng)
            self.guarded.on_stalled = self.filter.replace_stalled
        else:
            self._redraws = RedrawnMembers(settings)
            self.guarded.on_stalled = self._redraw_stalled
            self.guarded.replaced_with = 'its state, under a fresh draw of the germ'
        self.step_index = 0
        self._request = None
        self.latest = self._result(0.0)

    @property
    def simulator(self) -> Simulator:
        return self.guarded.simulator

    def start(self, steps: int, top_speeds_rad_per_s, hook_load_n: float, block=None,
              samples: tuple[Sample, ...] = ()) -> None:
        """
        Take a tick's work: ``steps`` model steps under what the rig applied in them.

        top_speeds_rad_per_s: the top speed at the end of each step, shape (steps,);
        block: None (every member under ``hook_load_n``, N), or the rig's block as (positions
        m, velocities m/s) at the end of each step, shapes (steps,): each member's line then
        hangs from it (:class:`~drill_twin.rig.drawworks.FollowedBlock`); samples: the
        rig's measurement samples received since the last tick (for the ensemble filter).
        """
        self._request = (steps, top_speeds_rad_per_s, hook_load_n, block, tuple(samples))

    def _redraw_stalled(self, stalled) -> dict[int, int]:
        """Replace open-loop members the batch cannot integrate (:class:`RedrawnMembers`)."""
        replaced, germs = self._redraws.choose(stalled, self.simulator.members)
        if replaced:
            self.simulator.copy_members(list(replaced), list(replaced.values()), germs=germs)
        return replaced

    def collect(self) -> EnsembleResult:
        """Do the pending tick's work, if any, and return the ensemble's latest result."""
        if self._request is None:
            return self.latest
        start = time.perf_counter()
        steps, speeds, hook, block, samples = self._request
        self._request = None
        if self.filter is not None:
            for sample in samples:
                self.filter.offer(sample)                # a refusal is kept in its refusals
        if block is None:
            self.rig.set_axial_mode(AxialMode.HOOK_LOAD)
            self.rig.set_hook_load(hook)
        iterations = 0
        for step in range(steps):
            self.rig.follow_top_speed(speeds[step])
            if block is not None:
                positions, velocities = block
                self.rig.follow_block(positions[step], velocities[step])
            result = self.guarded.step()
            if result is not None:
                self.step_index += 1
                iterations += result.iterations
                if self.filter is not None:
                    self.filter.after_step()
                    if self.filter.parameters_written:
                        integrator = self.simulator.integrator
                        self.guarded.guard.set_germs(integrator.germ, integrator.law_scales)
        analyses, events = (), ()
        if self.filter is not None:
            analyses = tuple(self.filter.take_history())
            events = tuple(measurement_refused(self.simulator.time_s, problem)
                           for problem in self.filter.take_refusals())
        self.latest = self._result(iterations / max(steps, 1), time.perf_counter() - start,
                                   analyses, events)
        return self.latest

    def close(self) -> None:
        pass

    def _result(self, iterations_per_step: float, wall_s: float = 0.0, analyses=(),
                events=()) -> EnsembleResult:
        o = self.simulator.observe(detailed=0)
        bit = np.stack([getattr(o, name) for name in BIT_FIELDS], axis=1)
        return EnsembleResult(step=self.step_index, time_s=o.time_s, bit=bit,
                              touching_wall=int(o.in_contact.any(axis=1).sum()),
                              lifted_off=int(o.lifted.sum()),
                              events=tuple(self.guarded.take_events()) + tuple(events),
                              resets=self.guarded.resets,
                              iterations_per_step=float(iterations_per_step),
                              wall_s=float(wall_s), analyses=analyses,
                              samples_used=self.filter.samples_used if self.filter else 0,
                              samples_refused=self.filter.samples_refused if self.filter else 0)


def measurement_refused(time_s: float, problem: str) -> TwinEvent:
    """Return the event of a measurement sample the twin could not use (it goes on)."""
    return TwinEvent('measurement_rejected', 'warn', time_s,
                     f'measurement refused: {problem}', {'reason': problem})


class EnsembleProcess:
    """
    The ensemble integrated in a worker process, one tick ahead of ``collect``.

    The worker is ``python -m drill_twin.twin.ensemble_worker`` (a fresh interpreter: nothing
    of this process, its main module or its ROS context is inherited) talking over a socket
    pair; it ignores SIGINT (a Ctrl-C reaches the whole process group; the parent decides
    when to stop) and ends when told, or when the parent's end of the socket closes.

    Made in two parts, so that the worker's start-up (its imports, about 1.3 s here) runs
    while the caller builds its own model: the constructor starts the process,
    :meth:`begin` hands it the string and waits for its first result.
    """

    def __init__(self):
        ours, theirs = socket.socketpair()
        environment = dict(os.environ, **SINGLE_THREADED_BLAS)
        # The worker must import this very drill_twin, even when it was put on sys.path by
        # hand; last, so that it shadows nothing of the caller's PYTHONPATH.
        package_root = str(Path(__file__).resolve().parents[2])
        environment['PYTHONPATH'] = os.pathsep.join(
            filter(None, [os.environ.get('PYTHONPATH'), package_root]))
        try:
            self._process = subprocess.Popen(
                [sys.executable, '-m', WORKER_MODULE, str(theirs.fileno())],
                pass_fds=[theirs.fileno()], env=environment,
                stdin=subprocess.DEVNULL)
        finally:
            theirs.close()
        self._connection = multiprocessing.connection.Connection(ours.detach())
        self._pending = False
        self.latest = None

    def begin(self, config: DrillStringConfig, settings: EnsembleSettings,
              system) -> EnsembleProcess:
        """Hand the worker its ensemble and wait for the first result; return self."""
        try:
            try:
                self._connection.send((config, settings, system))
            except OSError as error:
                raise EnsembleFailed(self._ended(error)) from None
            self.latest = self._receive(WORKER_START_TIMEOUT_S)
        except EnsembleFailed:
            self.close()
            raise
        return self

    def start(self, steps: int, top_speeds_rad_per_s, hook_load_n: float, block=None,
              samples: tuple[Sample, ...] = ()) -> None:
        try:
            self._connection.send((steps, top_speeds_rad_per_s, hook_load_n, block,
                                   tuple(samples)))
        except OSError as error:
            raise EnsembleFailed(self._ended(error)) from None
        self._pending = True

    def collect(self) -> EnsembleResult:
        if self._pending:
            self._pending = False
            self.latest = self._receive(WORKER_REPLY_TIMEOUT_S)
        return self.latest

    def _receive(self, timeout_s: float) -> EnsembleResult:
        try:
            if not self._connection.poll(timeout_s):
                raise EnsembleFailed(f'the ensemble worker did not answer within '
                                     f'{timeout_s:g} s')
            status, payload = self._connection.recv()
        except (EOFError, OSError) as error:
            raise EnsembleFailed(self._ended(error)) from None
        if status != 'ok':
            raise EnsembleFailed(f'the ensemble worker failed: {payload}')
        return payload

    def _ended(self, error) -> str:
        try:
            code = self._process.wait(timeout=1.0)
        except subprocess.TimeoutExpired:
            return f'lost the ensemble worker process ({type(error).__name__})'
        return f'the ensemble worker process ended (exit code {code})'

    def close(self) -> None:
        """Stop the worker (politely, then by force) and release the socket."""
        if self._process.poll() is None:
            try:
                self._connection.send(None)
            except OSError:
                pass
            try:
                self._process.wait(timeout=2.0)
            except subprocess.TimeoutExpired:
                self._process.kill()
                self._process.wait(timeout=2.0)
        self._connection.close()


def serve(connection) -> None:
    """Run the worker's loop: build the ensemble, then one result per request."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        config, settings, system = connection.recv()
        with threadpool_limits(limits=1, user_api='blas'):
            ensemble = LocalEnsemble(config, settings, system)
            connection.send(('ok', ensemble.latest))
            while True:
                try:
                    request = connection.recv()
                except EOFError:
                    return
                if request is None:
                    return
                ensemble.start(*request)
                connection.send(('ok', ensemble.collect()))
    except (EOFError, OSError):
        return
    except Exception as error:                     # reported to the parent, which goes on
        try:
            connection.send(('error', f'{type(error).__name__}: {error}'))
        except OSError:
            pass


def start_worker(settings: EnsembleSettings) -> EnsembleProcess | None:
    """Start the worker process of ``settings``'s ensemble, if it has one (else None)."""
    if settings.members == 0 or not settings.separate_process:
        return None
    return EnsembleProcess()


def open_ensemble(config: DrillStringConfig, settings: EnsembleSettings, system,
                  worker: EnsembleProcess | None = None):
    """
    Start the ensemble of ``settings`` (None without members), here or in a worker process.

    ``worker``: the process :func:`start_worker` started for it (one is started here if
    None and the ensemble runs in a process of its own).
    """
    if settings.members == 0:
        return None
    if not settings.separate_process:
        return LocalEnsemble(config, settings, system)
    return (worker or EnsembleProcess()).begin(config, settings, system)
