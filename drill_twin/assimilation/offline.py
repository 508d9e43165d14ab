"""
The ensemble filter run over a recorded rig log, beside the same ensemble in open loop.

One Simulator holds 2N members: members 0..N-1 are analysed, members N..2N-1 are the same
initial ensemble (the same germs) left in open loop, so that both see the same commands and
the same numerics. The commands of the log are applied at their times.

The filter is the twin's (:class:`~drill_twin.assimilation.sequential.SequentialFilter`):
each sample is handed to it at its arrival time in the log; analyses happen every
1 / analysis_rate_hz of model time with every sample that has arrived since the last one,
each compared with what the members predicted at its stamp (a delayed mud-pulse sample
included: an ensemble smoother step).
"""
from __future__ import annotations

import math

from dataclasses import dataclass, field

import numpy as np

from drill_twin.assimilation.bounds import interval
from drill_twin.assimilation.measurements import SENSOR_CHANNELS
from drill_twin.assimilation.rig_log import RigLog, command_at
from drill_twin.assimilation.sequential import Sample, SequentialFilter
from drill_twin.assimilation.settings import SENSOR_OF, AssimilationConfig
from drill_twin.assimilation.state import law_scales_for_members
from drill_twin.config.schema import DrillStringConfig
from drill_twin.integrator.simulator import Simulator
from drill_twin.integrator.stepping import GuardedSimulator
from drill_twin.rig.rig import Rig
from drill_twin.uncertainty.germ import germs_for_realizations


@dataclass
class Estimate:
    """
    The filter's and the open loop's bit speed, and the filter's record.

    The bit speeds are at the truth's times (or at the analysis times without a truth).
    time_s (k,); filtered and open_loop: (k, N) the members' bit speeds (rad/s), summarised
    by :meth:`bounds`; hole_depth_m (k, 2): the analysed and the open-loop members' mean hole
    depth (m); analysis_time_s (a,), nis (a,), measurements (a,) per analysis;
    germ_mean and germ_lower/upper (a, 3): G11, G12, G22 of the analysed members after each
    analysis; law_mean and law_lower/upper (a, 5): their factors of a1 ... a5 (NaN unless
    the law is estimated); hole_rate_observed, hole_rate_predicted (a,): the block's slope over
    the window an analysis closed and the members' mean own slope (m/s; NaN: no window closed,
    :mod:`.hole_rate`); bias_channels: the channels whose sensor bias is estimated, bias_mean
    and bias_lower/upper (a, b): its mean and 95 % bounds over the analysed members (SI;
    :mod:`.sequential`); filtered_weight_on_bit_n and filtered_rop_m_per_s (k, N): the
    analysed members' WOB (N, > 0 pressing) and their bits' ROP (m/s, their own steps'
    velocity) at the same instants as the bit speeds.
    """

    time_s: list = field(default_factory=list)
    filtered: list = field(default_factory=list)
    open_loop: list = field(default_factory=list)
    filtered_weight_on_bit_n: list = field(default_factory=list)
    filtered_rop_m_per_s: list = field(default_factory=list)
    hole_depth_m: list = field(default_factory=list)
    analysis_time_s: list = field(default_factory=list)
    nis: list = field(default_factory=list)
    measurements: list = field(default_factory=list)
    germ_mean: list = field(default_factory=list)
    germ_lower: list = field(default_factory=list)
    germ_upper: list = field(default_factory=list)
    law_mean: list = field(default_factory=list)
    law_lower: list = field(default_factory=list)
    law_upper: list = field(default_factory=list)
    hole_rate_observed: list = field(default_factory=list)
    hole_rate_predicted: list = field(default_factory=list)
    bias_channels: tuple = ()
    bias_mean: list = field(default_factory=list)
    bias_lower: list = field(default_factory=list)
    bias_upper: list = field(default_factory=list)
    resets: int = 0
    replaced: int = 0
    """Members that could not be integrated any more, replaced by copies of others."""
    final_germs: np.ndarray | None = None
    """(N, 2, 2) the analysed members' germs at the end of the log."""
    final_law_scales: np.ndarray | None = None
    """(N, 5) the analysed members' factors of a1 ... a5 at the end of the log."""

    def add(self, record) -> None:
        """Keep an analysis (:class:`~drill_twin.assimilation.sequential.AnalysisRecord`)."""
        self.analysis_time_s.append(record.time_s)
        self.nis.append(record.nis)
        self.measurements.append(record.measurements)
        self.germ_mean.append(record.germ_mean)
        self.germ_lower.append(record.germ_lower)
        self.germ_upper.append(record.germ_upper)
        self.law_mean.append(record.law_mean)
        self.law_lower.append(record.law_lower)
        self.law_upper.append(record.law_upper)
        self.hole_rate_observed.append(record.hole_rate_observed_m_per_s)
        self.hole_rate_predicted.append(record.hole_rate_predicted_m_per_s)
        self.bias_channels = record.bias_channels
        self.bias_mean.append(record.bias_mean)
        self.bias_lower.append(record.bias_lower)
        self.bias_upper.append(record.bias_upper)

    def bounds(self, which: str = 'filtered', method: str = 'student_t') -> np.ndarray:
        """(k, 3): mean, lower and upper 95 % bound of the bit speed (rad/s)."""
        return np.array([interval(values, method) for values in getattr(self, which)]
                        ).reshape(-1, 3)

    def arrays(self) -> dict[str, np.ndarray]:
        return {name: np.asarray(getattr(self, name), dtype=float) for name in (
            'time_s', 'filtered', 'open_loop', 'filtered_weight_on_bit_n',
            'filtered_rop_m_per_s', 'hole_depth_m', 'analysis_time_s', 'nis', 'measurements',
            'germ_mean', 'germ_lower', 'germ_upper', 'law_mean', 'law_lower', 'law_upper',
            'hole_rate_observed', 'hole_rate_predicted', 'bias_mean', 'bias_lower',
            'bias_upper')}


def run_filter(config: DrillStringConfig, settings: AssimilationConfig, log: RigLog, *,
               analyse_on: bool = True, system=None, progress=None,
               open_loop: bool = True) -> Estimate:
    """
    Return the filter over ``log`` (module docstring); ``analyse_on=False`` runs no analysis.

    ``open_loop=False``: without the open-loop copies (the batch holds the analysed members
    only, as the twin's ensemble does; ``Estimate.open_loop`` stays empty and nothing can be
    scored against it).
    """
    spec = settings.filter
    n = spec.members
    copies = 2 if open_loop else 1
    germs = germs_for_realizations(spec.prior_dispersion, spec.seed, range(n))
    scales = None
    if spec.parameters == 'law':
        scales = np.concatenate([law_scales_for_members(spec.law_prior_log_std, spec.seed, n)]
                                * copies)
    sim = Simulator(config, copies * n, germs=np.concatenate([germs] * copies), system=system,
                    law_scales=scales)
    rig = Rig(sim)
    rng = np.random.default_rng(np.random.SeedSequence(spec.seed, spawn_key=(1,)))
    sequential = SequentialFilter(sim, n, settings, rng)
    guarded = GuardedSimulator(     # a stalled member: a copy of another of its half
        rig, first_member=1, name='ensemble members',
        on_stalled=lambda stalled: sequential.replace_stalled(
            stalled, [range(n), range(n, 2 * n)][:copies]))
    dt = sim.dt
    steps = int(round(log.duration_s / dt))
    analysis_every = sequential.analysis_every
    arrivals = sorted(
        [(float(arrival), sensor, k) for sensor, samples in log.sensors.items()
         for k, arrival in enumerate(samples.arrival_s)
         if any(c in spec.measurements for c in SENSOR_CHANNELS[sensor])]
        + [(float(arrival), channel, k) for channel, samples in log.scalars.items()
           for k, arrival in enumerate(samples.arrival_s) if channel in spec.measurements])
    truth_steps = set()
    if log.truth is not None:
        truth_steps = set(np.round(log.truth.time_s / dt).astype(int).tolist())
    estimate = Estimate()
    next_arrival = 0
    for step in range(1, steps + 1):
        start = (step - 1) * dt
        rig.set_top_drive_speed(command_at(log.speed_commands, start))
        rig.set_hook_load(command_at(log.hook_commands, start))
        guarded.step()
        time = step * dt
        while next_arrival < len(arrivals) and arrivals[next_arrival][0] <= time + 1e-9:
            _, sensor, index = arrivals[next_arrival]
            next_arrival += 1
            if analyse_on:
                sequential.offer(_sample(log, sensor, index, spec.measurements))
        record = sequential.after_step()
        if sequential.parameters_written:
            guarded.guard.set_germs(sim.integrator.germ, sim.integrator.law_scales)
        if record is not None:
            estimate.add(record)
        if step in truth_steps or (log.truth is None and step % analysis_every == 0):
            speed = sim.last.bit_speed_rad_per_s
            estimate.time_s.append(time)
            estimate.filtered.append(speed[:n].copy())
            if open_loop:
                estimate.open_loop.append(speed[n:].copy())
            estimate.filtered_weight_on_bit_n.append(-sim.last.weight_on_bit_n[:n])
            estimate.filtered_rop_m_per_s.append(sim.last.rop_m_per_s[:n].copy())
            hole = sim.hole_depth_m
            estimate.hole_depth_m.append((float(hole[:n].mean()),
                                          float(hole[n:].mean()) if open_loop else math.nan))
        if progress is not None and step % 200 == 0:
            progress(time, log.duration_s)
    estimate.resets = guarded.resets
    estimate.replaced = sequential.replaced
    if spec.parameters != 'none':
        estimate.final_germs = sequential.state.germs()
    if spec.parameters == 'law':
        estimate.final_law_scales = sequential.state.law_scales()
    return estimate


def _sample(log: RigLog, sensor: str, index: int, channels) -> Sample:
    """
    Sample ``index`` of ``sensor`` in the log, with the channels among ``channels``.

    ``sensor``: a sensor's name, or a channel's that came on a topic of its own.
    """
    if sensor in log.scalars:
        samples = log.scalars[sensor]
        return Sample(SENSOR_OF[sensor], float(samples.stamp_s[index]),
                      {sensor: float(samples.values[sensor][index])})
    samples = log.sensors[sensor]
    return Sample(sensor, float(samples.stamp_s[index]),
                  {c: float(samples.values[c][index]) for c in SENSOR_CHANNELS[sensor]
                   if c in channels and c in samples.values})


def summarise(estimate: Estimate, log: RigLog, settle_s: float,
              method: str = 'student_t') -> dict:
    """
    Return the scores over the log after ``settle_s`` (needs the truth).

    The contract keys bit_speed_rms_error_rad_per_s, open_loop_bit_speed_rms_error_rad_per_s,
    bit_speed_coverage_95, and a few more.
    """
    if log.truth is None:
        raise ValueError('the log holds no truth to score against')
    a = estimate.arrays()
    truth = np.interp(a['time_s'], log.truth.time_s, log.truth.bit_speed_rad_per_s)
    keep = a['time_s'] >= settle_s
    if not keep.any():
        raise ValueError(f'nothing of the log is after the settling time {settle_s:g} s')
    truth = truth[keep]
    filtered = estimate.bounds('filtered', method)[keep]
    open_loop = estimate.bounds('open_loop', method)[keep]

    def rms(x):
        return float(np.sqrt(np.mean((x - truth) ** 2)))

    inside = (filtered[:, 1] <= truth) & (truth <= filtered[:, 2])
    inside_open = (open_loop[:, 1] <= truth) & (truth <= open_loop[:, 2])
    summary = {
        'bit_speed_rms_error_rad_per_s': rms(filtered[:, 0]),
        'open_loop_bit_speed_rms_error_rad_per_s': rms(open_loop[:, 0]),
        'bit_speed_coverage_95': float(inside.mean()),
        'open_loop_bit_speed_coverage_95': float(inside_open.mean()),
        'truth_bit_speed_rms_about_its_mean_rad_per_s': float(np.std(truth)),
        'settle_s': float(settle_s),
        'bounds': method,
        'scored_samples': int(keep.sum()),
        'analyses': int(a['nis'].size),
        'resets': int(estimate.resets),
        'members_replaced': int(estimate.replaced),
    }
    if a['nis'].size:
        late = a['analysis_time_s'] >= settle_s
        nis = a['nis'][late] if late.any() else a['nis']
        count = a['measurements'][late] if late.any() else a['measurements']
        summary['mean_nis_per_measurement'] = float(np.mean(nis / count))
        summary['germ_mean_final'] = [float(v) for v in a['germ_mean'][-1]]
        if np.all(np.isfinite(a['law_mean'][-1])):
            summary['law_scales_mean_final'] = [float(v) for v in a['law_mean'][-1]]
        if estimate.bias_channels:
            summary['sensor_bias_final'] = {
                channel: {'mean': float(a['bias_mean'][-1][j]),
                          'lower': float(a['bias_lower'][-1][j]),
                          'upper': float(a['bias_upper'][-1][j])}
                for j, channel in enumerate(estimate.bias_channels)}
    return summary
