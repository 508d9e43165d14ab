"""A whole Monte Carlo study: run the chunks, gather them by index, compute the statistics."""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from drill_twin.config.loader import config_to_dict
from drill_twin.config.schema import DrillStringConfig
from drill_twin.uncertainty import statistics
from drill_twin.uncertainty.montecarlo import QUANTITIES, ChunkResult, StudySpec, run_chunk

COV_KEYS = {'rop': 'rop_m_per_s', 'weight_on_bit': 'weight_on_bit_n',
            'torque_on_bit': 'torque_on_bit_nm', 'bit_speed': 'bit_speed_rad_per_s'}


@dataclass
class StudyResult:
    """
    The realizations of a study, in index order, and the mean model.

    time_s: window instants (n_w,); indices: completed realizations (n,); realizations:
    quantity -> (n, n_w); mean_model: quantity -> (n_w,); norm_integral, impacts, lift_offs,
    impacts_in_window, lift_offs_in_window: (n,); failed: index -> (time_s, message).
    """

    spec: StudySpec
    config: DrillStringConfig
    time_s: np.ndarray
    indices: np.ndarray
    realizations: dict
    mean_model: dict
    norm_integral: np.ndarray
    impacts: np.ndarray
    lift_offs: np.ndarray
    impacts_in_window: np.ndarray
    lift_offs_in_window: np.ndarray
    failed: dict = field(default_factory=dict)
    wall_s: float = 0.0
    workers: int = 1

    @property
    def time_step_s(self) -> float:
        return float(np.median(np.diff(self.time_s)))

    def coefficient_of_variation(self) -> dict[str, float]:
        """Per-instant CoV across realizations averaged over the window (the paper's)."""
        return {key: float(statistics.mean_coefficient_of_variation_per_instant(
            self.realizations[name])) if len(self.indices) > 1 else float('nan')
                for key, name in COV_KEYS.items()}

    def coefficient_of_variation_of_time_average(self) -> dict[str, float]:
        """Return the CoV across realizations of each realization's window average."""
        return {key: float(statistics.coefficient_of_variation_of_time_average(
            self.realizations[name])) if len(self.indices) > 1 else float('nan')
                for key, name in COV_KEYS.items()}

    def convergence(self) -> np.ndarray:
        """conv(n_s) of Eq. 54 for n_s = 1 .. n (realizations in index order)."""
        return statistics.mean_square_convergence(self.norm_integral)

    def envelopes(self) -> dict:
        """Return quantity -> Envelope (mean, 2.5 %, 97.5 %) in time, shape (n_w,) each."""
        return {q: statistics.envelope(self.realizations[q]) for q in QUANTITIES}

    def spectra(self):
        """
        Return (frequency_hz, quantity -> (mean-model spectrum, Envelope)).

        Of the mean-removed window signals (one-sided amplitude spectra).
        """
        out = {}
        frequency = None
        for q in QUANTITIES:
            frequency, model = _spectrum(self.mean_model[q][None], self.time_step_s)
            _, realizations = _spectrum(self.realizations[q], self.time_step_s)
            out[q] = (model[0], statistics.envelope(realizations))
        return frequency, out


def _spectrum(signals, dt):
    centred = signals - signals.mean(axis=-1, keepdims=True)
    return statistics.fourier_modulus(centred, dt, scaling='amplitude')


def run_study(config: DrillStringConfig, spec: StudySpec, executor,
              progress: Callable[[int, int], None] | None = None) -> StudyResult:
    """
    Run the mean model and every chunk of ``spec`` on ``executor``.

    progress(done, total) counts runs: the mean model and the realizations. The mean model is
    integrated with the first chunk (montecarlo module docstring).
    """
    config_json = json.dumps(config_to_dict(config))
    start = time.perf_counter()
    chunks = spec.chunks()
    arguments = [(config_json, spec, chunks[0], True)] + [(config_json, spec, chunk)
                                                          for chunk in chunks[1:]]
    results, done = [], 0
    for result in executor.run(run_chunk, arguments):
        results.append(result)
        done += (result.indices.size + len(result.failed)
                 + (result.mean_model is not None))
        if progress is not None:
            progress(done, spec.samples + 1)
    mean = next(r for r in results if r.mean_model is not None)
    return _gather(config, spec, mean, results, time.perf_counter() - start,
                   getattr(executor, 'workers', 1))


def _gather(config, spec, mean: ChunkResult, chunks: list[ChunkResult], wall_s, workers):
    indices = np.concatenate([c.indices for c in chunks])
    order = np.argsort(indices)

    def stack(getter):
        return np.concatenate([getter(c) for c in chunks])[order]

    failed = {}
    for c in chunks:
        failed.update(c.failed)
    return StudyResult(
        spec=spec, config=config, time_s=mean.time_s, indices=indices[order],
        realizations={q: np.concatenate([c.series[q] for c in chunks])[order]
                      for q in QUANTITIES},
        mean_model={q: mean.mean_model[q] for q in QUANTITIES},
        norm_integral=stack(lambda c: c.norm_integral), impacts=stack(lambda c: c.impacts),
        lift_offs=stack(lambda c: c.lift_offs),
        impacts_in_window=stack(lambda c: c.impacts_in_window),
        lift_offs_in_window=stack(lambda c: c.lift_offs_in_window),
        failed=dict(sorted(failed.items())), wall_s=wall_s, workers=workers)
