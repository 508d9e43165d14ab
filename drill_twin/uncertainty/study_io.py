"""
The files of a Monte Carlo study (docs/MONTECARLO.md describes them).

- summary.json: the study's parameters and seed, coefficients of variation over the
  stationary window, event counts, failures and timing.
- statistics.npz: time_s and frequency_hz, then for each quantity Q (rop_m_per_s,
  bit_speed_rad_per_s, weight_on_bit_n, torque_on_bit_nm, radial_displacement_m):
  Q__mean_model, Q__mean, Q__lower (2.5 %), Q__upper (97.5 %) over the window, and
  Q__spectrum_mean_model, Q__spectrum_mean, Q__spectrum_lower, Q__spectrum_upper (one-sided
  amplitude spectra of the mean-removed window signals, in Q's unit); samples and conv
  (Eq. 54); station_m.
- convergence.csv: samples, conv (Eq. 54).
- config.yaml: the complete model configuration of the study (``drill-twin montecarlo
  --config config.yaml`` with the same options repeats it).
- realizations.npz: index and, per quantity, the window series of every realization
  (float32, (n, n_w)).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import yaml

from drill_twin.config.loader import config_to_dict
from drill_twin.uncertainty.montecarlo import QUANTITIES
from drill_twin.uncertainty.study import StudyResult


def summary(result: StudyResult) -> dict:
    spec = result.spec
    conv = result.convergence()
    simulated = (len(result.indices) + 1) * spec.duration_s
    return {
        'samples': spec.samples,
        'delta': spec.dispersion,
        'seed': spec.seed,
        'duration_s': spec.duration_s,
        'window_s': spec.window_s,
        'batch_size': spec.batch_size,
        'station_m': spec.station_m,
        'time_step_s': result.config.integration.time_step_s,
        'completed_realizations': int(len(result.indices)),
        'coefficient_of_variation': result.coefficient_of_variation(),
        'coefficient_of_variation_of_time_average':
            result.coefficient_of_variation_of_time_average(),
        'realizations_with_impacts': int(np.sum(result.impacts > 0)),
        'realizations_with_lift_off': int(np.sum(result.lift_offs > 0)),
        'realizations_with_impacts_in_window': int(np.sum(result.impacts_in_window > 0)),
        'realizations_with_lift_off_in_window': int(np.sum(result.lift_offs_in_window > 0)),
        'failed_realizations': [{'index': int(i), 'time_s': float(t), 'message': m}
                                for i, (t, m) in result.failed.items()],
        'mean_model': {q: float(np.mean(result.mean_model[q])) for q in QUANTITIES},
        'stochastic_mean': {q: float(np.mean(result.realizations[q])) for q in QUANTITIES},
        'conv_final': float(conv[-1]) if conv.size else None,
        'workers': result.workers,
        'wall_time_s': result.wall_s,
        'simulated_seconds_per_wall_second': simulated / result.wall_s if result.wall_s else None,
    }


def write_study(result: StudyResult, directory: str | Path) -> Path:
    """Write every file of the study into ``directory`` (created if needed)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    (directory / 'summary.json').write_text(json.dumps(summary(result), indent=2) + '\n')
    (directory / 'config.yaml').write_text(
        yaml.safe_dump(config_to_dict(result.config), sort_keys=False))
    frequency, spectra = result.spectra()
    arrays = {'time_s': result.time_s, 'frequency_hz': frequency,
              'station_m': np.array(result.spec.station_m)}
    for q, envelope in result.envelopes().items():
        arrays[f'{q}__mean_model'] = result.mean_model[q]
        arrays[f'{q}__mean'] = envelope.mean
        arrays[f'{q}__lower'] = envelope.lower
        arrays[f'{q}__upper'] = envelope.upper
        model, spectral = spectra[q]
        arrays[f'{q}__spectrum_mean_model'] = model
        arrays[f'{q}__spectrum_mean'] = spectral.mean
        arrays[f'{q}__spectrum_lower'] = spectral.lower
        arrays[f'{q}__spectrum_upper'] = spectral.upper
    conv = result.convergence()
    samples = np.arange(1, conv.size + 1)
    arrays['samples'] = samples
    arrays['conv'] = conv
    np.savez_compressed(directory / 'statistics.npz', **arrays)
    np.savetxt(directory / 'convergence.csv', np.column_stack([samples, conv]), delimiter=',',
               header='samples,conv', comments='', fmt=['%d', '%.10g'])
    np.savez_compressed(directory / 'realizations.npz', index=result.indices,
                        time_s=result.time_s,
                        **{q: result.realizations[q].astype(np.float32) for q in QUANTITIES})
    return directory
