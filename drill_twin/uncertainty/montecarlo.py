"""
Monte Carlo study of the random bit-rock law (paper Sect. 3-4, Eq. 51-54).

Realizations are integrated in fixed chunks of ``batch_size`` consecutive indices; realization
j of a study with seed s gets the germ drawn from its own stream (seed, j). A chunk is computed
the same way whichever process or machine runs it, so a study gives identical results for any
number of workers and on a Dask cluster.

The mean model rides in the first chunk as one more member, with the germ [G] = I: the random
law then equals the mean law exactly (its deviation terms vanish), and a member costs a
batch far less than a run of its own, which would hold one worker for a large share of a
small study while the other waited. Like any batch neighbour, it changes the realizations only
by rounding.

Each chunk returns, per realization: the stationary-window series of ROP, bit speed, WOB,
TOB and the radial displacement at the study's station; the time integral of ||U||^2 over
the whole run (U the full DOF vector from the prestressed state, with the driven rotation:
Eq. 54); the impacts and lift-offs (episodes, Simulator.impact_count).
"""
from __future__ import annotations

import functools
import json
import time
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import threadpool_limits

from drill_twin.config.loader import build_config
from drill_twin.model.reduced_system import build_reduced_system
from drill_twin.integrator.simulator import SimulationDiverged, Simulator
from drill_twin.modal.reduced_basis import modal_analysis
from drill_twin.rig.rig import Rig
from drill_twin.uncertainty.germ import germs_for_realizations, validate_dispersion

QUANTITIES = ('rop_m_per_s', 'bit_speed_rad_per_s', 'weight_on_bit_n', 'torque_on_bit_nm',
              'radial_displacement_m')
MEAN_MODEL_GERM = np.eye(2)
"""The germ that makes the random bit-rock law the mean law (Eq. 50 with [G_b] = I)."""
LARGEST_BATCH = 64
"""Cap of the default batch size: a step's fixed cost is shared by the members of a batch
(measured: 64 members integrate about twice as many member-seconds per CPU second as 16)."""


def default_batch_size(samples: int, workers: int) -> int:
    """
    Chunks of equal size, a multiple of ``workers`` of them, none above LARGEST_BATCH.

    Every worker then gets the same work (the first chunk's extra member, the mean model,
    costs a fraction of a member). The results depend on the batch size only by rounding;
    summary.json records it, and ``--batch-size`` repeats a study bit for bit.
    """
    workers = max(1, int(workers))
    chunks = max(1, -(-samples // LARGEST_BATCH))
    chunks = workers * -(-chunks // workers)
    return max(1, -(-samples // chunks))


@dataclass(frozen=True)
class StudySpec:
    """What a study computes (SI units)."""

    dispersion: float
    samples: int
    duration_s: float
    seed: int
    window_s: float
    batch_size: int
    station_m: float

    def __post_init__(self):
        validate_dispersion(self.dispersion)
        if self.samples < 1:
            raise ValueError(f'samples: must be at least 1, got {self.samples}')
        if not self.duration_s > 0:
            raise ValueError(f'duration: must be positive, got {self.duration_s}')
        if not 0 < self.window_s <= self.duration_s:
            raise ValueError(f'window: must lie in (0, duration], got {self.window_s}')
        if self.batch_size < 1:
            raise ValueError(f'batch size: must be at least 1, got {self.batch_size}')
        if self.seed < 0:
            raise ValueError(f'seed: must be >= 0, got {self.seed}')

    def chunks(self) -> list[tuple[int, ...]]:
        """Return the fixed partition of realization indices into chunks."""
        return [tuple(range(start, min(start + self.batch_size, self.samples)))
                for start in range(0, self.samples, self.batch_size)]


@dataclass
class ChunkResult:
    """
    What a chunk of realizations returns (arrays per realization on the first axis).

    indices: (k,); time_s: the window's instants (n_w,); series: quantity -> (k, n_w);
    norm_integral: integral of ||U||^2 dt over the run, (k,); impacts, lift_offs: counted
    over the run, (k,); impacts_in_window, lift_offs_in_window: (k,); failed: index ->
    (time_s, message) of realizations that diverged (not in the arrays); steps, wall_s;
    mean_model: quantity -> (n_w,) window series of the mean model in the chunk that carried
    it, else None.
    """

    indices: np.ndarray
    time_s: np.ndarray
    series: dict
    norm_integral: np.ndarray
    impacts: np.ndarray
    lift_offs: np.ndarray
    impacts_in_window: np.ndarray
    lift_offs_in_window: np.ndarray
    failed: dict = field(default_factory=dict)
    steps: int = 0
    wall_s: float = 0.0
    mean_model: dict | None = None


@functools.lru_cache(maxsize=4)
def _system_for(config_json: str):
    """Return the reduced system of a configuration, built once per process."""
    config = build_config(json.loads(config_json))
    model, _, basis = modal_analysis(config)
    return config, build_reduced_system(model, basis)


def run_chunk(config_json: str, spec: StudySpec, indices: tuple[int, ...],
              mean_model: bool = False) -> ChunkResult:
    """
    Integrate the realizations ``indices`` for the study's duration.

    With the mean model as one more member when ``mean_model``.

    ``config_json`` is the configuration as a JSON mapping (it travels to other processes).
    Realizations that diverge are reported in ``failed`` and the chunk is rerun without them;
    a diverging mean model stops the study.
    """
    config, system = _system_for(config_json)
    germs = germs_for_realizations(spec.dispersion, spec.seed, indices)
    if mean_model:
        germs = np.concatenate([MEAN_MODEL_GERM[None], germs])
    if germs.shape[0] == 0:
        return _empty(config, spec)
    leading = 1 if mean_model else 0                      # batch position of indices[0]
    with threadpool_limits(limits=1, user_api='blas'):
        try:
            result = _integrate(config, system, spec, np.array(indices, dtype=int), germs,
                                leading)
        except SimulationDiverged as error:
            bad_members = [m for m in error.members if m >= leading]
            if (mean_model and 0 in error.members) or not bad_members:
                raise
            bad = {indices[m - leading]: (error.time_s, str(error)) for m in bad_members}
            rest = tuple(i for i in indices if i not in bad)
            result = run_chunk(config_json, spec, rest, mean_model)
            result.failed.update(bad)
        return result


def _station_index(system, station_m: float) -> int:
    positions = np.array([s.x_m for s in system.stations])
    if positions.size == 0 or np.min(np.abs(positions - station_m)) > 1e-6:
        raise ValueError(f'the study needs an output station at x = {station_m} m '
                         f'(output.stations_m = {positions.tolist()})')
    return int(np.argmin(np.abs(positions - station_m)))


def _window_steps(config, spec):
    dt = config.integration.time_step_s
    every = max(1, int(round(config.output.record_interval_s / dt)))
    steps = int(round(spec.duration_s / dt))
    first = steps - int(round(spec.window_s / dt))
    first -= first % every
    return dt, every, steps, first


def _empty(config, spec) -> ChunkResult:
    dt, every, steps, first = _window_steps(config, spec)
    n_window = (steps - first) // every + 1
    return ChunkResult(np.zeros(0, int), first * dt + every * dt * np.arange(n_window),
                       {q: np.zeros((0, n_window)) for q in QUANTITIES}, np.zeros(0),
                       np.zeros(0, int), np.zeros(0, int), np.zeros(0, int), np.zeros(0, int))


def _integrate(config, system, spec: StudySpec, indices, germs, leading: int) -> ChunkResult:
    """
    Integrate the batch of ``germs``.

    Members ``leading:`` are the realizations ``indices`` (member 0 is the mean model when
    ``leading`` is 1).
    """
    members = germs.shape[0]
    simulator = Simulator(config, members=members, germs=germs, system=system)
    rig = Rig(simulator)
    station = _station_index(system, spec.station_m)
    rows = system.stations[station].rows
    dt, every, steps, first = _window_steps(config, spec)
    n_window = (steps - first) // every + 1
    series = {q: np.zeros((members, n_window)) for q in QUANTITIES}
    time_s = np.zeros(n_window)
    theta_x = system.field(1)
    norm_integral = np.zeros(members)
    previous_norm = None
    impacts_at_window = lift_offs_at_window = None
    start = time.perf_counter()
    for k in range(steps + 1):
        if k > 0:
            rig.step()
        if k % every:
            continue
        u = system.physical(simulator.state.q)
        u[:, theta_x] += simulator.state.top_angle_rad
        norm = np.einsum('md,md->m', u, u)
        if previous_norm is not None:
            norm_integral += 0.5 * (norm + previous_norm) * every * dt
        previous_norm = norm
        if k >= first:
            j = (k - first) // every
            forces = simulator.last
            time_s[j] = simulator.time_s
            series['rop_m_per_s'][:, j] = simulator.hole_rop_m_per_s(forces.rop_m_per_s)
            series['bit_speed_rad_per_s'][:, j] = forces.bit_speed_rad_per_s
            series['weight_on_bit_n'][:, j] = forces.weight_on_bit_n
            series['torque_on_bit_nm'][:, j] = forces.torque_on_bit_nm
            v, w = rows[1] @ u.T, rows[2] @ u.T           # station rows: u, v, w, ...
            series['radial_displacement_m'][:, j] = np.hypot(v, w)
            if impacts_at_window is None:
                impacts_at_window = simulator.impact_count.copy()
                lift_offs_at_window = simulator.lift_off_count.copy()
    realizations = slice(leading, None)
    return ChunkResult(
        indices=indices, time_s=time_s,
        series={q: values[realizations] for q, values in series.items()},
        norm_integral=norm_integral[realizations],
        impacts=simulator.impact_count[realizations].copy(),
        lift_offs=simulator.lift_off_count[realizations].copy(),
        impacts_in_window=(simulator.impact_count - impacts_at_window)[realizations],
        lift_offs_in_window=(simulator.lift_off_count - lift_offs_at_window)[realizations],
        steps=steps, wall_s=time.perf_counter() - start,
        mean_model={q: values[0].copy() for q, values in series.items()} if leading else None)
