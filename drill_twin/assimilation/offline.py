"""
The ensemble filter run over a recorded rig log, beside the same ensemble in open loop.

One Simulator holds 2N members: members 0..N-1 are analysed, members N..2N-1 are the same
initial ensemble (the same germs) left in open loop, so that both see the same commands and
the same numerics. The commands of the log are applied at their times.

Analyses happen every 1 / analysis_rate_hz of model time and use every sample that has
arrived since the last one. A delayed sample (mud-pulse) is compared with what each member
predicted at the sample's stamp: the members' predictions are kept from the stamp until
the sample arrives, and every analysis in between updates them with the same member
transform as the state (an ensemble smoother step: for linear dynamics the cross
covariance of the present state and the past prediction is then the right one).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.stats import t as student_t

from drill_twin.assimilation.filter import analyse
from drill_twin.assimilation.measurements import SENSOR_CHANNELS, channel_values
from drill_twin.assimilation.rig_log import RigLog, command_at
from drill_twin.assimilation.settings import AssimilationConfig
from drill_twin.assimilation.state import MemberState
from drill_twin.config.schema import DrillStringConfig
from drill_twin.dynamics.simulator import Simulator
from drill_twin.twin.stepping import GuardedSimulator
from drill_twin.uncertainty.germ import germs_for_realizations

BOUNDS = (2.5, 97.5)
"""Percentiles of the ensemble reported as its 95 % bounds (bounds: percentile)."""


@dataclass
class Estimate:
    """
    The filter's and the open loop's bit speed, and the filter's record.

    The bit speeds are at the truth's times (or at the analysis times without a truth).
    time_s (k,); filtered and open_loop: (k, N) the members' bit speeds (rad/s), summarised
    by :meth:`bounds`; analysis_time_s (a,), nis (a,), measurements (a,) per analysis;
    germ_mean and germ_lower/upper (a, 3): G11, G12, G22 of the analysed members after each
    analysis.
    """

    time_s: list = field(default_factory=list)
    filtered: list = field(default_factory=list)
    open_loop: list = field(default_factory=list)
    analysis_time_s: list = field(default_factory=list)
    nis: list = field(default_factory=list)
    measurements: list = field(default_factory=list)
    germ_mean: list = field(default_factory=list)
    germ_lower: list = field(default_factory=list)
    germ_upper: list = field(default_factory=list)
    resets: int = 0

    def bounds(self, which: str = 'filtered', method: str = 'student_t') -> np.ndarray:
        """(k, 3): mean, lower and upper 95 % bound of the bit speed (rad/s)."""
        return np.array([interval(values, method) for values in getattr(self, which)]
                        ).reshape(-1, 3)

    def arrays(self) -> dict[str, np.ndarray]:
        return {name: np.asarray(getattr(self, name), dtype=float) for name in (
            'time_s', 'filtered', 'open_loop', 'analysis_time_s', 'nis', 'measurements',
            'germ_mean', 'germ_lower', 'germ_upper')}


def interval(values: np.ndarray, method: str = 'student_t') -> np.ndarray:
    """
    (mean, lower, upper) 95 % bounds from an ensemble's values (N,).

    student_t: the 95 % prediction interval of a new draw from the Gaussian the N members
    are drawn from, mean -+ t_{0.975, N-1} s sqrt(1 + 1/N) (s the sample standard
    deviation): it covers the truth 95 % of the time when the truth is one more such draw.
    percentile: the members' 2.5 % and 97.5 % percentiles, which for N exchangeable members
    hold the truth at most (N - 1)/(N + 1) of the time (78 % for N = 8): too narrow for a
    small ensemble.
    """
    values = np.asarray(values, dtype=float)
    mean = values.mean()
    if method == 'percentile':
        low, high = np.percentile(values, BOUNDS)
        return np.array([mean, low, high])
    n = values.size
    half = student_t.ppf(0.975, n - 1) * values.std(ddof=1) * np.sqrt(1.0 + 1.0 / n)
    return np.array([mean, mean - half, mean + half])


def run_filter(config: DrillStringConfig, settings: AssimilationConfig, log: RigLog, *,
               analyse_on: bool = True, system=None, progress=None) -> Estimate:
    """Return the filter over ``log`` (module docstring); ``analyse_on=False`` runs no analysis."""
    spec = settings.filter
    n = spec.members
    germs = germs_for_realizations(spec.prior_dispersion, spec.seed, range(n))
    sim = Simulator(config, 2 * n, germs=np.concatenate([germs, germs]), system=system)
    guarded = GuardedSimulator(sim, first_member=1, name='ensemble members')
    members = MemberState(sim, n, spec.blocks, spec.parameters)
    rng = np.random.default_rng(np.random.SeedSequence(spec.seed, spawn_key=(1,)))
    dt = sim.dt
    steps = int(round(log.duration_s / dt))
    analysis_every = max(1, int(round(1.0 / (spec.analysis_rate_hz * dt))))
    used = [c for c in spec.measurements]
    # Samples to use: (sensor, index, channels); predictions are stored at their stamp.
    stamp_step, arrivals = {}, []
    for sensor, samples in log.sensors.items():
        channels = [c for c in SENSOR_CHANNELS[sensor] if c in used]
        if not channels or samples.stamp_s.size == 0:
            continue
        for index, (stamp, arrival) in enumerate(zip(samples.stamp_s, samples.arrival_s)):
            step = int(round(stamp / dt))
            if 1 <= step <= steps:
                stamp_step.setdefault(step, []).append((sensor, index, tuple(channels)))
                arrivals.append((arrival, sensor, index, tuple(channels)))
    arrivals.sort()
    truth_steps = set()
    if log.truth is not None:
        truth_steps = set(np.round(log.truth.time_s / dt).astype(int).tolist())
    predicted = {}                       # (sensor, index) -> (N, len(channels))
    estimate = Estimate()
    next_arrival = 0
    for step in range(1, steps + 1):
        start = (step - 1) * dt
        sim.set_top_drive_speed(command_at(log.speed_commands, start))
        sim.set_hook_load(command_at(log.hook_commands, start))
        guarded.step()
        if step in stamp_step:
            o = sim.observe(detailed=n)
            for sensor, index, channels in stamp_step[step]:
                predicted[(sensor, index)] = np.stack(
                    [channel_values(o, c, n) for c in channels], axis=1)
        if analyse_on and step % analysis_every == 0:
            time = step * dt
            ready = []
            while next_arrival < len(arrivals) and arrivals[next_arrival][0] <= time + 1e-9:
                ready.append(arrivals[next_arrival])
                next_arrival += 1
            ready = [r for r in ready if (r[1], r[2]) in predicted]
            if ready:
                _analyse(members, settings, log, ready, predicted, rng, estimate, time)
        if step in truth_steps or (log.truth is None and step % analysis_every == 0):
            speed = sim.last.bit_speed_rad_per_s
            estimate.time_s.append(step * dt)
            estimate.filtered.append(speed[:n].copy())
            estimate.open_loop.append(speed[n:].copy())
        if progress is not None and step % 200 == 0:
            progress(step * dt, log.duration_s)
    estimate.resets = guarded.resets
    return estimate


def _analyse(members: MemberState, settings: AssimilationConfig, log: RigLog, ready,
             predicted, rng, estimate: Estimate, time: float) -> None:
    """
    One analysis with the ``ready`` samples.

    Updates the members and the stored predictions of the samples still to come.
    """
    Y, y, variance = [], [], []
    for _, sensor, index, channels in ready:
        prediction = predicted.pop((sensor, index))
        for column, channel in enumerate(channels):
            Y.append(prediction[:, column])
            measured = float(log.sensors[sensor].values[channel][index])
            y.append(measured)
            variance.append(float(settings.channel(channel).std(prediction[:, column].mean()))
                            ** 2)
    Y = np.stack(Y, axis=1)
    variance = np.maximum(np.asarray(variance), 1e-12)
    spec = settings.filter
    result = analyse(Y, np.asarray(y), variance, method=spec.method, inflation=spec.inflation,
                     relaxation=spec.relaxation, rng=rng)
    analysed = result.apply(members.extract())
    sigma = spec.model_error_bit_speed_rad_per_s
    if sigma > 0:                         # additive inflation: centred, the mean unchanged
        kicks = sigma * rng.standard_normal(analysed.shape[0])
        analysed += np.outer(kicks - kicks.mean(), members.bit_speed_direction())
    members.write(analysed)
    for key in predicted:                                     # samples not yet arrived
        predicted[key] = result.apply(predicted[key])
    germs = members.germs()
    g = np.stack([germs[:, 0, 0], germs[:, 0, 1], germs[:, 1, 1]], axis=1)
    estimate.analysis_time_s.append(time)
    estimate.nis.append(result.nis)
    estimate.measurements.append(result.measurements)
    estimate.germ_mean.append(g.mean(axis=0))
    estimate.germ_lower.append(np.percentile(g, BOUNDS[0], axis=0))
    estimate.germ_upper.append(np.percentile(g, BOUNDS[1], axis=0))


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
    }
    if a['nis'].size:
        late = a['analysis_time_s'] >= settle_s
        nis = a['nis'][late] if late.any() else a['nis']
        count = a['measurements'][late] if late.any() else a['measurements']
        summary['mean_nis_per_measurement'] = float(np.mean(nis / count))
        summary['germ_mean_final'] = [float(v) for v in a['germ_mean'][-1]]
    return summary
