"""The twin node's parameters: names, defaults, ranges, descriptions, and which are safe to
change while it runs (config/twin.yaml sets them under ``drill_twin: ros__parameters:``)."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ParameterSpec:
    """One parameter. ``safe``: may change at run time (otherwise refused with a reason)."""

    name: str
    default: object
    description: str
    safe: bool
    low: float | None = None
    high: float | None = None
    choices: tuple = ()


PARAMETERS = (
    ParameterSpec('model_config', '', 'model configuration YAML (empty: the built-in defaults, '
                  'config/ritto2009.yaml)', safe=False),
    ParameterSpec('model_overrides', (), 'key=value overrides of the model configuration, '
                  'e.g. sections.drill_pipe.elements=40', safe=False),
    ParameterSpec('ensemble_members', 16, 'realizations of the random bit-rock law stepped '
                  'with the mean model', safe=False, low=0, high=256),
    ParameterSpec('ensemble_dispersion', 0.01, 'dispersion delta of the ensemble\'s germs',
                  safe=False, low=0.0, high=0.65),
    ParameterSpec('ensemble_process', True, 'integrate the ensemble in a worker process (a '
                  'second core) one tick behind the mean model; false: in the node\'s process',
                  safe=False),
    ParameterSpec('seed', 0, 'seed of the ensemble (member j draws from the stream (seed, j))',
                  safe=False, low=0, high=2 ** 31 - 1),
    ParameterSpec('time_step_s', 0.01, 'model time step of the twin (s); every tick advances '
                  '1 / rate_hz in whole steps. 10 ms costs half the configuration\'s 5 ms '
                  '(offline runs) for 0.2 % error on the stick-slip swing; 0: the '
                  'configuration\'s', safe=False, low=0.0, high=0.1),
    ParameterSpec('rate_hz', 100.0, 'tick rate of the wall-clock timer; every tick advances '
                  '1 / rate_hz of simulated time in model steps', safe=False, low=1.0, high=1000.0),
    ParameterSpec('fast', False, 'run as fast as possible and publish /clock (also with '
                  'use_sim_time)', safe=False),
    ParameterSpec('duration_s', 0.0, 'stop after this much simulated time (0: run until '
                  'stopped)', safe=True, low=0.0, high=1e9),
    ParameterSpec('log_dir', 'runs', 'directory of the logs: each run is a rosbag2 bag '
                  '(a directory of MCAP splits and metadata.yaml) in it', safe=False),
    ParameterSpec('log_split_s', 300.0, 'log time (s) an MCAP split of the log holds at most '
                  '(rosbag2\'s max_bag_duration): only the split being written can be cut by '
                  'a crash or a full disk', safe=False, low=1.0, high=86400.0),
    ParameterSpec('log_enabled', True, 'record every topic and command to an MCAP log',
                  safe=False),
    ParameterSpec('on_log_error', 'continue', 'if the log cannot be written: continue (run '
                  'without a log) or exit', safe=True, choices=('continue', 'exit')),
    ParameterSpec('ensemble_rate_hz', 10.0, 'publication rate of the ensemble mean and bounds',
                  safe=True, low=0.1, high=1000.0),
    ParameterSpec('kpi_rate_hz', 10.0, 'publication rate of the drilling KPIs', safe=True,
                  low=0.1, high=1000.0),
    ParameterSpec('health_rate_hz', 1.0, 'publication rate of the twin-health diagnostics',
                  safe=True, low=0.01, high=100.0),
    ParameterSpec('kpi_window_s', 10.0, 'moving window of the stick-slip severity and MSE (s)',
                  safe=True, low=0.1, high=3600.0),
    ParameterSpec('top_drive_speed_max_rad_per_s', 30.0, 'largest accepted top-drive speed '
                  'command (rad/s)', safe=True, low=0.0, high=100.0),
    ParameterSpec('hook_load_min_n', 0.0, 'smallest accepted hook-load command (N)', safe=True,
                  low=0.0, high=1e8),
    ParameterSpec('hook_load_max_n', 5.0e6, 'largest accepted hook-load command (N)', safe=True,
                  low=0.0, high=1e8),
)
BY_NAME = {p.name: p for p in PARAMETERS}


def unsafe_change_reason(name: str) -> str:
    """Why an unsafe parameter cannot change while the twin runs."""
    return (f'{name} cannot change while the twin runs: it sets up the model, the ensemble, '
            f'the clock or the log; restart the twin with the new value')


def markdown_table() -> str:
    """The parameter table of docs/ROS-INTERFACE.md."""
    def show(value):
        if isinstance(value, tuple):
            return '(empty list)' if not value else ', '.join(map(str, value))
        return repr(value)

    def span(p):
        if p.choices:
            return ', '.join(p.choices)
        number = (lambda x: str(x) if isinstance(x, int) else f'{x:g}')
        return '' if p.low is None else f'{number(p.low)} … {number(p.high)}'

    rows = ['| parameter | default | range | safe | meaning |', '|---|---|---|---|---|']
    rows += [f'| `{p.name}` | {show(p.default)} | {span(p)} | {"yes" if p.safe else "no"} | '
             f'{p.description} |' for p in PARAMETERS]
    return '\n'.join(rows)
