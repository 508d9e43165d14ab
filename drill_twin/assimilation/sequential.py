"""
The ensemble filter as it runs beside a batch being stepped: samples in, analyses out.

One implementation for the offline filter (:mod:`.offline`, samples delivered at their
arrival times in a log) and the twin's online ensemble (:mod:`drill_twin.twin.ensemble`,
samples delivered as the rig's messages come in). The caller steps the Simulator and calls
:meth:`SequentialFilter.after_step` after every step; samples are handed over with
:meth:`SequentialFilter.offer` whenever they arrive.

After every step each analysed member's predictions of the filter's channels are recorded
in a ring buffer covering the last ``horizon_s`` of model time. Every
1 / analysis_rate_hz of model time the samples whose stamp the batch has reached are
analysed together: each is compared with the members' predictions at its stamp (linearly
interpolated between the two steps around it; exact on a step), so a sample that arrives
late (mud-pulse telemetry, network latency, a twin lagging the rig) is compared with what
the members predicted when it was taken. Every analysis applies its member transform to the
buffer as well as to the state (an ensemble smoother step: exact for linear dynamics), so a
sample analysed later sees predictions consistent with the analysed state. With
``localisation: motion`` each motion's block takes the transform of its own channels'
analysis, and each channel's stored predictions that of its motion. A sample stamped
before the buffer's start is refused (too old); one stamped beyond the batch's time waits.

With ``increment_duration_s`` > 0 an analysis does not jump the members to their analysed
state: the increment (state and law, model error and walks included) is added in equal parts
over that many steps' worth of model time (an incremental analysis update, Bloom et al.
1996), the first part at the analysis. The bit-rock law ties the WOB to the bit's speed and
to its coefficients without inertia (a2 ~ 6e-8 m/(N s): 0.1 rad/s of bit speed is some
240 N), so a jump of either moves every member's WOB at once and the string rings; near the
law's cutting threshold that ringing is rectified into drilling the law does not do
(docs/ASSIMILATION.md). The stored predictions take the whole analysis at once (the members
reach it within the increment's duration). A new analysis first completes what is left of
the previous increment.

Sensor biases: a channel's known ``bias`` (its calibration offset) is subtracted from every
reading. A channel with ``bias_prior_std`` > 0 has a constant bias beyond it estimated with
the state: each member carries its own (drawn centred with that standard deviation), its
prediction of the channel is its model's value plus its bias, and the biases are analysed as
augmented parameters (the parameters' transform, a walk of ``bias_walk_std``, by default
``parameter_walk_std`` times their prior's standard deviation). Whether a bias is observable
depends on the channels: a constant offset of the surface torque and the law's constant
torque a5 look alike at any steady point (settings.BIAS_COUNTERPART, docs/ASSIMILATION.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from drill_twin.assimilation.bounds import BOUNDS_PERCENT
from drill_twin.assimilation.filter import analyse, no_information_transform
from drill_twin.assimilation.hole_rate import HoleRateWindows
from drill_twin.assimilation.measurements import MOTION_OF, SENSOR_CHANNELS, channel_values
from drill_twin.assimilation.settings import SENSOR_OF, AssimilationConfig
from drill_twin.assimilation.state import MemberState

LATE_TOLERANCE_S = 2.0
"""How much later than its sensor's stated delay a sample may still arrive (s)."""
EARLY_TOLERANCE_S = 5.0
"""How far ahead of the batch a sample's stamp may be (s): farther is a clock error."""


@dataclass(frozen=True)
class Sample:
    """
    One sensor's reading.

    ``stamp_s``: model time when sampled (s); ``values``: {channel: value in SI, the
    driller's signs} (:mod:`.measurements`).
    """

    sensor: str
    stamp_s: float
    values: dict


@dataclass(frozen=True)
class AnalysisRecord:
    """
    One analysis.

    Its model time (s), normalised innovation squared and number of measured values, the
    analysed members' germ entries (G11, G12, G22) and factors of the law's a1 ... a5: mean,
    2.5 % and 97.5 % (NaN where they are not estimated); the estimated sensor biases (SI: the
    reading minus the true value, beyond the channel's known ``bias``), likewise; the hole's
    rate (:mod:`.hole_rate`).
    """

    time_s: float
    nis: float
    measurements: int
    germ_mean: tuple
    germ_lower: tuple
    germ_upper: tuple
    law_mean: tuple = (math.nan,) * 5
    law_lower: tuple = (math.nan,) * 5
    law_upper: tuple = (math.nan,) * 5
    bias_channels: tuple = ()
    """The channels whose bias the filter estimates, in the order of bias_mean/lower/upper."""
    bias_mean: tuple = ()
    bias_lower: tuple = ()
    bias_upper: tuple = ()
    hole_rate_observed_m_per_s: float = math.nan
    hole_rate_predicted_m_per_s: float = math.nan
    """With ``hole_rate_window_s``: the block's slope over the window this analysis closed and
    the members' mean own slope before it (m/s; NaN: no window closed)."""


class _Measurements(NamedTuple):
    """What one analysis compares: m measured values and the N members' predictions of them."""

    predicted: np.ndarray
    """(N, m)."""
    observed: np.ndarray
    """(m,), SI, each channel's known bias removed."""
    variance: np.ndarray
    """(m,): the measurements' noise variances."""
    motions: list
    """The motion ('axial', 'torsional') each value informs."""
    used: int
    """How many samples the values come from."""


def sample_problem(sample: Sample) -> str | None:
    """Return why ``sample`` cannot be used (one phrase), or None."""
    if sample.sensor not in SENSOR_CHANNELS:
        return f'unknown sensor {sample.sensor!r}'
    if not math.isfinite(sample.stamp_s):
        return f'{sample.sensor} sample stamp {sample.stamp_s} is not finite'
    for channel, value in sample.values.items():
        if SENSOR_OF.get(channel) != sample.sensor:
            return f'{sample.sensor} sample carries {channel!r}, not one of its channels'
        if not math.isfinite(value):
            return f'{sample.sensor} sample: {channel} = {value} is not finite'
    return None


class SequentialFilter:
    """
    The ensemble filter over members 0..members-1 of ``simulator`` (module docstring).

    :param simulator: the batch (with germs when ``settings.filter.parameters`` is 'germ').
    :param members: how many of its first members are analysed (>= 2).
    :param settings: the filter, its channels' noise, the sensors' delays.
    :param rng: the Generator of the perturbed observations and the additive model error.
    :param horizon_s: how far back a sample's stamp may be (s); by default the largest delay
        of the sensors the filter uses plus LATE_TOLERANCE_S.
    """

    def __init__(self, simulator, members: int, settings: AssimilationConfig,
                 rng: np.random.Generator, horizon_s: float | None = None):
        spec = settings.filter
        self.simulator = simulator
        self.settings = settings
        self.state = MemberState(simulator, members, spec.blocks, spec.parameters)
        self.members = int(members)
        self.rng = rng
        self.channels = tuple(spec.measurements)
        dt = simulator.dt
        self.analysis_every = max(1, int(round(1.0 / (spec.analysis_rate_hz * dt))))
        if horizon_s is None:
            horizon_s = max(settings.sensor_of(c).delay_s for c in self.channels) \
                + LATE_TOLERANCE_S
        self.horizon_s = float(horizon_s)
        capacity = int(math.ceil(self.horizon_s / dt)) + 2
        self._times = np.full(capacity, -np.inf)
        self._predicted = np.zeros((capacity, self.members, len(self.channels)))
        self._records = 0
        self._steps = 0
        self._pending: list[Sample] = []
        self.analyses = 0
        self.samples_used = 0
        self.samples_refused = 0
        self.refusals: list[str] = []
        """Why samples were refused since the last :meth:`take_refusals`."""
        self.history: list[AnalysisRecord] = []
        """The analyses since the last :meth:`take_history`."""
        self.replaced = 0
        """Members replaced by copies of others (:meth:`replace_stalled`)."""
        self._donors = rng.spawn(1)[0]     # its own stream: the filter's draws are unchanged
        self.hole_rate = None
        """The hole's rate windows (:mod:`.hole_rate`), with ``hole_rate_window_s``."""
        self.bias_channels = settings.estimated_bias_channels()
        self._bias_prior_std = np.array([settings.channel(c).bias_prior_std
                                         for c in self.bias_channels])
        self._bias_walk_std = np.array([
            spec.parameter_walk_std * settings.channel(c).bias_prior_std
            if settings.channel(c).bias_walk_std is None else settings.channel(c).bias_walk_std
            for c in self.bias_channels])
        self._bias_column = {self.channels.index(c): j for j, c in enumerate(self.bias_channels)}
        draws = np.random.default_rng(np.random.SeedSequence(spec.seed, spawn_key=(3,))
                                      ).standard_normal((self.members, len(self.bias_channels)))
        self.channel_bias = self._bias_prior_std * (draws - draws.mean(axis=0))
        """(N, b): each analysed member's bias of each of ``bias_channels`` (SI)."""
        self.increment_steps = max(1, int(round(spec.increment_duration_s / dt)))
        """Steps over which an analysis's increment is added (1: at once)."""
        self._increment = None            # (N, size): the part added at each step, or None
        self._increment_left = 0          # how many parts are still to be added
        self.parameters_written = False
        """Whether the last :meth:`after_step` changed the members' germs or laws (then the
        state guard takes them: ``GuardedSimulator.guard.set_germs``)."""
        self._motion_columns = self.state.motion_columns()
        self._block_column = (self.channels.index('block_position')
                              if 'block_position' in self.channels else None)
        if spec.hole_rate_window_s is not None:
            self.hole_rate = HoleRateWindows(
                simulator, self.members, spec.hole_rate_window_s, simulator.time_s,
                settings.sensors.hook.delay_s, spec.hole_rate_prediction == 'steady_law')

    # -- members that cannot be integrated -----------------------------------------------
    def replace_stalled(self, stalled, pools=None) -> dict[int, int]:
        """
        Replace members the batch cannot integrate any more by copies of others: {member: donor}.

        An analysis can move a member's germ or law to where the model, from any state, breaks
        a physical bound (the state guard's); rather than stall the whole ensemble, such a
        member is resampled: it becomes a copy (state and parameters,
        :meth:`Simulator.copy_members`) of a member drawn at random among the healthy ones of
        its pool, as a particle filter resamples; inflation spreads the two again. ``pools``:
        the groups of member indices that may stand in for each other (default: the analysed
        members; the offline filter adds its open-loop copies as a pool of their own). A pool
        with no healthy member replaces nothing.
        """
        pools = pools or [range(self.members)]
        stalled = set(int(m) for m in stalled)
        replaced = {}
        for pool in pools:
            pool = [int(m) for m in pool]
            targets = [m for m in pool if m in stalled]
            healthy = [m for m in pool if m not in stalled]
            if not targets or not healthy:
                continue
            for target in targets:
                replaced[target] = int(self._donors.choice(healthy))
        if replaced:
            targets, sources = zip(*sorted(replaced.items()))
            self.simulator.copy_members(list(targets), list(sources))
            ours = [(t, s) for t, s in zip(targets, sources)
                    if t < self.members and s < self.members]
            for target, source in ours:
                self._predicted[:, target] = self._predicted[:, source]
                self.channel_bias[target] = self.channel_bias[source]
                if self._increment is not None:
                    self._increment[target] = self._increment[source]
            if self.hole_rate is not None and ours:
                self.hole_rate.copy(*zip(*ours))
            self.replaced += len(replaced)
        return replaced

    # -- samples in ----------------------------------------------------------------------
    def offer(self, sample: Sample) -> str | None:
        """
        Take a sample; return why it is refused (one phrase, also kept in ``refusals``).

        Only the filter's channels of the sample are used; a sample with none of them is
        accepted and ignored.
        """
        problem = sample_problem(sample)
        now = self.simulator.time_s
        if problem is None and sample.stamp_s < now - self.horizon_s:
            problem = (f'{sample.sensor} sample stamped {sample.stamp_s:.3f} s is older than '
                       f'the {self.horizon_s:g} s the filter looks back (model time '
                       f'{now:.3f} s)')
        if problem is None and sample.stamp_s > now + EARLY_TOLERANCE_S:
            problem = (f'{sample.sensor} sample stamped {sample.stamp_s:.3f} s is more than '
                       f'{EARLY_TOLERANCE_S:g} s ahead of the model ({now:.3f} s)')
        if problem is not None:
            self._refuse(problem)
            return problem
        if any(c in self.channels for c in sample.values):
            self._pending.append(sample)
        if self.hole_rate is not None and 'block_position' in sample.values:
            self.hole_rate.offer(sample.stamp_s, sample.values['block_position'])
        return None

    def _refuse(self, problem: str) -> None:
        self.samples_refused += 1
        self.refusals.append(problem)

    def take_refusals(self) -> list[str]:
        refusals, self.refusals = self.refusals, []
        return refusals

    def take_history(self) -> list[AnalysisRecord]:
        history, self.history = self.history, []
        return history

    # -- stepping ------------------------------------------------------------------------
    def after_step(self) -> AnalysisRecord | None:
        """
        Record the members' predictions; analyse when due; return the analysis, if any.

        First this step's part of the last analysis's increment is added, if one is left.
        """
        self.parameters_written = False
        if self._increment_left > 0:
            self._add_increment(1)
        self._record()
        self._steps += 1
        if self._steps % self.analysis_every:
            return None
        record = self._analyse_ready()
        self.parameters_written |= record is not None and self.state.parameter_count > 0
        return record

    def _add_increment(self, parts: int) -> None:
        """Add ``parts`` of the pending increment to the members' state."""
        parts = min(parts, self._increment_left)
        vectors = self.state.extract() + parts * self._increment
        self._increment_left -= parts
        if self._increment_left == 0:
            self._increment = None
        self.state.write(vectors)
        if self.hole_rate is not None:
            self.hole_rate.after_write()
        self.parameters_written |= self.state.parameter_count > 0

    def _record(self) -> None:
        o = self.simulator.observe(detailed=self.members)
        slot = self._records % self._times.size
        self._times[slot] = o.time_s
        for column, channel in enumerate(self.channels):
            self._predicted[slot, :, column] = channel_values(o, channel, self.members)
        for column, j in self._bias_column.items():
            self._predicted[slot, :, column] += self.channel_bias[:, j]
        if self.hole_rate is not None:
            m = self.members
            self.hole_rate.after_step(o.time_s, self._predicted[slot, :, self._block_column],
                                      o.speed_rad_per_s[:m], -o.weight_on_bit_n[:m])
        self._records += 1

    def _prediction_at(self, stamp_s: float) -> np.ndarray | None:
        """Return the members' predictions (N, channels) at ``stamp_s`` (None: not kept)."""
        slots = np.flatnonzero(np.isfinite(self._times))
        if slots.size == 0:
            return None
        slots = slots[np.argsort(self._times[slots])]
        t = self._times[slots]
        if not t[0] - 1e-9 <= stamp_s <= t[-1] + 1e-9:
            return None
        k = min(int(np.searchsorted(t, stamp_s - 1e-9)), t.size - 1)
        if k == 0 or abs(t[k] - stamp_s) <= 1e-9:
            return self._predicted[slots[k]]
        weight = (stamp_s - t[k - 1]) / (t[k] - t[k - 1])
        return ((1.0 - weight) * self._predicted[slots[k - 1]]
                + weight * self._predicted[slots[k]])

    def _analyse_ready(self) -> AnalysisRecord | None:
        """Analyse the samples (and hole-rate windows) the batch has reached; None: no analysis."""
        now = self.simulator.time_s
        ready = [s for s in self._pending if s.stamp_s <= now + 1e-9]
        rates = [] if self.hole_rate is None else self.hole_rate.due(
            now, self.settings.channel('block_position').std)
        if not ready and not rates:
            return None
        self._pending = [s for s in self._pending if s.stamp_s > now + 1e-9]
        measured = self._measurements(ready, rates)
        if measured is None:
            return None
        if self._increment_left > 0:          # the previous analysis's, not yet all added
            self._add_increment(self._increment_left)
        forecast = np.concatenate([self.state.extract(), self.channel_bias], axis=1)
        skipped, unused = f'analysis at {now:.3f} s skipped', f'({measured.used} sample(s) unused)'
        if not (np.all(np.isfinite(measured.predicted)) and np.all(np.isfinite(forecast))):
            self._refuse(f'{skipped}: the members\' predictions or state are not finite {unused}')
            return None
        try:
            result, local = self._transforms(measured)
        except (np.linalg.LinAlgError, ValueError) as error:
            self._refuse(f'{skipped}: {error} {unused}')
            return None
        analysed = self._analysed(forecast, result, local)
        if not np.all(np.isfinite(analysed)):
            self._refuse(f'{skipped}: it is not finite {unused}')
            return None
        target = self._write(analysed, forecast)
        if self.hole_rate is not None:
            self.hole_rate.transform(result.transform if local is None else local['axial'])
            self.hole_rate.after_write()
        self.samples_used += measured.used
        self._smooth_predictions(forecast, result, local)
        self.analyses += 1
        record = self._summary(now, result, target, rates[-1] if rates else None)
        self.history.append(record)
        return record

    def _measurements(self, ready: list[Sample], rates: list) -> _Measurements | None:
        """
        Gather the measured values and the members' predictions of them.

        The hole-rate windows due, then the ready samples' values with the predictions at their
        stamps; a sample stamped before the buffer is refused. None: nothing to analyse.
        """
        predicted, observed, variance, motions, used = [], [], [], [], 0
        for rate in rates:
            predicted.append(rate.predicted)
            observed.append(rate.observed_m_per_s)
            variance.append(rate.variance)
            motions.append('axial')
        for sample in ready:
            prediction = self._prediction_at(sample.stamp_s)
            if prediction is None:
                self._refuse(f'{sample.sensor} sample stamped {sample.stamp_s:.3f} s is '
                             f'before what the filter recorded (from {self._oldest():.3f} s)')
                continue
            for column, channel in enumerate(self.channels):
                if channel not in sample.values:
                    continue
                predicted.append(prediction[:, column])
                observed.append(float(sample.values[channel])
                                - self.settings.channel(channel).bias)
                variance.append(float(self.settings.channel(channel).std(
                    prediction[:, column].mean())) ** 2)
                motions.append(MOTION_OF[channel])
            used += 1
        if not observed:
            return None
        return _Measurements(np.stack(predicted, axis=1), np.asarray(observed),
                             np.maximum(np.asarray(variance), 1e-12), motions, used)

    def _transforms(self, measured: _Measurements):
        """Return the analysis (:func:`.filter.analyse`) and, localised, each motion's own."""
        spec = self.settings.filter
        args = (measured.predicted, measured.observed, measured.variance)
        result = analyse(*args, method=spec.method, inflation=spec.inflation,
                         relaxation=spec.relaxation, rng=self.rng,
                         parameter_inflation=spec.parameter_inflation,
                         parameter_relaxation=spec.parameter_relaxation)
        local = (self._motion_transforms(*args, measured.motions)
                 if spec.localisation == 'motion' else None)
        return result, local

    def _analysed(self, forecast: np.ndarray, result, local) -> np.ndarray:
        """Return the analysed members (N, size + biases): the transforms, then the kicks."""
        analysed = result.apply(forecast)
        count, size = self.state.parameter_count, self.state.size
        parameters = slice(size - count, None)        # the law's, then the sensors' biases
        if result.parameter_transform is not None:
            analysed[:, parameters] = result.parameter_transform @ forecast[:, parameters]
        if local is not None:
            for motion, columns in self._motion_columns.items():
                analysed[:, columns] = local[motion] @ forecast[:, columns]
        spec = self.settings.filter
        sigma = spec.model_error_bit_speed_rad_per_s
        if sigma > 0:                         # additive inflation: centred, the mean unchanged
            kicks = sigma * self.rng.standard_normal(analysed.shape[0])
            analysed[:, :size] += np.outer(kicks - kicks.mean(),
                                           self.state.bit_speed_direction())
        walk = spec.parameter_walk_std
        if walk > 0 and count:                # the same for the parameters: centred kicks
            kicks = walk * self.rng.standard_normal((analysed.shape[0], count))
            analysed[:, size - count:size] += kicks - kicks.mean(axis=0)
        if np.any(self._bias_walk_std > 0):   # the biases' walk
            kicks = self._bias_walk_std * self.rng.standard_normal(self.channel_bias.shape)
            analysed[:, size:] += kicks - kicks.mean(axis=0)
        return analysed

    def _write(self, analysed: np.ndarray, forecast: np.ndarray) -> np.ndarray:
        """
        Write the analysis to the members and the biases; return the analysed state (N, size).

        With an increment the members take its first part only; the record reports the whole.
        """
        size = self.state.size
        target = analysed[:, :size].copy()
        if self.increment_steps > 1:         # the first of its parts now, the rest step by step
            self._increment = (analysed[:, :size] - forecast[:, :size]) / self.increment_steps
            self._increment_left = self.increment_steps - 1
            analysed[:, :size] = forecast[:, :size] + self._increment
        self.state.write(analysed[:, :size])
        self.channel_bias = analysed[:, size:].copy()
        return target

    def _smooth_predictions(self, forecast: np.ndarray, result, local) -> None:
        """
        Apply the analysis to the predictions still to be compared with late samples.

        The smoother step: a biased channel's prediction is the model's part, transformed as
        the state, plus the member's new bias.
        """
        size = self.state.size
        for column, j in self._bias_column.items():
            self._predicted[:, :, column] -= forecast[:, size + j]
        if local is None:
            self._predicted = np.matmul(result.transform, self._predicted)     # (t, N, c)
        else:                                 # a new buffer, as above: views stay as they were
            self._predicted = np.stack(
                [np.matmul(local[MOTION_OF[channel]], self._predicted[:, :, column, None])[..., 0]
                 for column, channel in enumerate(self.channels)], axis=2)
        for column, j in self._bias_column.items():
            self._predicted[:, :, column] += self.channel_bias[:, j]

    def _motion_transforms(self, Y: np.ndarray, y: np.ndarray, variance: np.ndarray,
                           motions: list) -> dict[str, np.ndarray]:
        """
        Return each motion's own analysis transform, from its channels' measurements only.

        {'axial', 'torsional'}: (N, N) each; a motion no measurement of this analysis
        informs keeps its mean (:func:`no_information_transform`).
        """
        spec, motions = self.settings.filter, np.asarray(motions)
        transforms = {}
        for motion in ('axial', 'torsional'):
            rows = np.flatnonzero(motions == motion)
            if rows.size == 0:
                transforms[motion] = no_information_transform(self.members, spec.inflation,
                                                              spec.relaxation)
                continue
            transforms[motion] = analyse(Y[:, rows], y[rows], variance[rows],
                                         method=spec.method, inflation=spec.inflation,
                                         relaxation=spec.relaxation, rng=self.rng).transform
        return transforms

    def _oldest(self) -> float:
        finite = self._times[np.isfinite(self._times)]
        return float(finite.min()) if finite.size else math.nan

    def _summary(self, time_s: float, result, analysed: np.ndarray,
                 rate=None) -> AnalysisRecord:
        """
        Return the record of an analysis, its parameters as analysed (``analysed``: (N, size)).

        With an incremental update the members reach them within the increment's duration.
        """
        germ, law = ((math.nan,) * 3,) * 3, ((math.nan,) * 5,) * 3
        germs, scales = self.state.parameters_of(analysed)
        if germs is not None:                 # G11, G12, G22
            germ = _mean_and_bounds(np.stack([germs[:, 0, 0], germs[:, 0, 1], germs[:, 1, 1]],
                                             axis=1))
        if scales is not None:
            law = _mean_and_bounds(scales)
        bias = _mean_and_bounds(self.channel_bias) if self.bias_channels else ((),) * 3
        observed, predicted = ((rate.observed_m_per_s, float(rate.predicted.mean()))
                               if rate is not None else (math.nan, math.nan))
        return AnalysisRecord(time_s=float(time_s), nis=float(result.nis),
                              measurements=result.measurements, germ_mean=germ[0],
                              germ_lower=germ[1], germ_upper=germ[2], law_mean=law[0],
                              law_lower=law[1], law_upper=law[2],
                              bias_channels=self.bias_channels, bias_mean=bias[0],
                              bias_lower=bias[1], bias_upper=bias[2],
                              hole_rate_observed_m_per_s=observed,
                              hole_rate_predicted_m_per_s=predicted)


def _mean_and_bounds(values: np.ndarray) -> tuple[tuple, tuple, tuple]:
    """Mean, 2.5 % and 97.5 % percentiles of the members' values (N, k), as tuples."""
    low, high = np.percentile(values, BOUNDS_PERCENT, axis=0)
    return (tuple(map(float, values.mean(axis=0))), tuple(map(float, low)),
            tuple(map(float, high)))
