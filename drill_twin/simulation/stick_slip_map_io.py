"""
The files of a stick-slip map (docs/MAP.md describes them).

- map.csv: one row per grid point (WOB-major), the columns of
  :data:`drill_twin.simulation.stick_slip_map.COLUMNS` in that order, with a header row.
- linear_stability.csv: the linear stability on a fine grid over the map's range
  (top_drive_speed_rad_per_s, weight_on_bit_n, growth_rate_per_s, frequency_hz,
  steady_rop_m_per_s).
- map.json: the grid, options, seed, wall time, workers and the failed points.
- config.yaml: the complete model configuration (``drill-twin map --config config.yaml``
  with the same options repeats the map).
- map.png: the heat map of the stick-slip severity (drawn by drill_twin.viz.map_figure).
"""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import yaml

from drill_twin.config.loader import config_to_dict, load_config
from drill_twin.simulation.stick_slip_map import COLUMNS, MapResult, MapSpec

TEXT_COLUMNS = ('linear_comparison', 'error')
INTEGER_COLUMNS = ('backward_rotation', 'lift_off_count', 'impact_count', 'linearly_stable',
                   'failed')


def _text(name: str, value) -> str:
    if name in TEXT_COLUMNS:
        return str(value)
    if name in INTEGER_COLUMNS and not (isinstance(value, float) and math.isnan(value)):
        return str(int(value))
    return f'{float(value):.9g}'


def write_map(result: MapResult, directory: str | Path) -> Path:
    """Write every file of the map into ``directory`` (created if needed)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    with open(directory / 'map.csv', 'w', newline='') as stream:
        writer = csv.writer(stream, lineterminator='\n')
        writer.writerow(COLUMNS)
        for row in result.rows:
            writer.writerow([_text(name, row[name]) for name in COLUMNS])
    with open(directory / 'linear_stability.csv', 'w', newline='') as stream:
        writer = csv.writer(stream, lineterminator='\n')
        writer.writerow(['top_drive_speed_rad_per_s', 'weight_on_bit_n', 'growth_rate_per_s',
                         'frequency_hz', 'steady_rop_m_per_s'])
        for i, wob in enumerate(result.boundary_weights_on_bit_n):
            for j, speed in enumerate(result.boundary_speeds_rad_per_s):
                writer.writerow([f'{speed:.9g}', f'{wob:.9g}',
                                 f'{result.boundary_growth_rate_per_s[i, j]:.9g}',
                                 f'{result.boundary_frequency_hz[i, j]:.9g}',
                                 f'{result.boundary_steady_rop_m_per_s[i, j]:.9g}'])
    (directory / 'map.json').write_text(json.dumps(summary(result), indent=2) + '\n')
    (directory / 'config.yaml').write_text(
        yaml.safe_dump(config_to_dict(result.config), sort_keys=False))
    return directory


def read_map(directory: str | Path) -> MapResult:
    """Read a map back from its files (to redraw or analyse it without rerunning)."""
    directory = Path(directory)
    info = json.loads((directory / 'map.json').read_text())
    spec = MapSpec(**{key: info[key] for key in ('speeds_rad_per_s', 'weights_on_bit_n',
                                                 'duration_s', 'window_s', 'start', 'seed',
                                                 'perturbation_rad_per_s')})
    with open(directory / 'map.csv', newline='') as stream:
        rows = [{name: _value(name, text) for name, text in row.items()}
                for row in csv.DictReader(stream)]
    for index, row in enumerate(rows):
        row['index'] = index
    grid = np.genfromtxt(directory / 'linear_stability.csv', delimiter=',', names=True)
    speeds = np.unique(grid['top_drive_speed_rad_per_s'])
    weights = np.unique(grid['weight_on_bit_n'])
    shape = (weights.size, speeds.size)
    return MapResult(spec=spec, config=load_config(directory / 'config.yaml'), rows=rows,
                     boundary_speeds_rad_per_s=speeds, boundary_weights_on_bit_n=weights,
                     boundary_growth_rate_per_s=grid['growth_rate_per_s'].reshape(shape),
                     boundary_frequency_hz=grid['frequency_hz'].reshape(shape),
                     boundary_steady_rop_m_per_s=grid['steady_rop_m_per_s'].reshape(shape),
                     wall_s=info['wall_time_s'], workers=info['workers'])


def _value(name: str, text: str):
    if name in TEXT_COLUMNS:
        return text
    if name in INTEGER_COLUMNS and text != 'nan':
        return int(text)
    return float(text)


def markdown_table() -> str:
    """Return the columns of map.csv as a Markdown table (docs/MAP.md prints it)."""
    lines = ['| column | meaning |', '|---|---|']
    lines += [f'| `{name}` | {meaning} |' for name, meaning in COLUMNS.items()]
    return '\n'.join(lines)


def summary(result: MapResult) -> dict:
    """Return the map's parameters, timing and failures."""
    spec = result.spec
    points = len(result.rows)
    return {
        'speeds_rad_per_s': list(spec.speeds_rad_per_s),
        'weights_on_bit_n': list(spec.weights_on_bit_n),
        'duration_s': spec.duration_s,
        'window_s': spec.window_s,
        'start': spec.start,
        'perturbation_rad_per_s': spec.perturbation_rad_per_s,
        'seed': spec.seed,
        'time_step_s': result.config.integration.time_step_s,
        'points': points,
        'linear_comparison': {verdict: sum(r['linear_comparison'] == verdict
                                           for r in result.rows)
                              for verdict in ('agree', 'disagree', 'near_boundary', 'failed')},
        'failed_points': [{'top_drive_speed_rad_per_s': r['top_drive_speed_rad_per_s'],
                           'weight_on_bit_n': r['weight_on_bit_n'],
                           'time_s': r['failed_time_s'], 'error': r['error']}
                          for r in result.failed_points()],
        'workers': result.workers,
        'wall_time_s': result.wall_s,
        'simulated_seconds_per_wall_second':
            points * spec.duration_s / result.wall_s if result.wall_s else None,
    }
