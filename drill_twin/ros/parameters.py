"""
The twin node's parameters.

Names, defaults, ranges, descriptions, and which are safe to change while it runs
(config/twin.yaml sets them under ``drill_twin: ros__parameters:``).
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, make_dataclass, replace


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

    def choices_text(self) -> str:
        """Return the choices as a message lists them ('' shown as '')."""
        return ', '.join(c if c else "''" for c in self.choices)


PARAMETERS = (
    ParameterSpec('model_config', '', 'model configuration YAML (empty: the built-in defaults, '
                  'config/ritto2009.yaml)', safe=False),
    ParameterSpec('model_overrides', (), 'key=value overrides of the model configuration, '
                  'e.g. sections.drill_pipe.elements=40', safe=False),
    ParameterSpec('ensemble_members', 64, 'realizations of the random bit-rock law stepped '
                  'with the mean model', safe=False, low=0, high=256),
    ParameterSpec('ensemble_dispersion', 0.01, 'dispersion delta of the ensemble\'s germs',
                  safe=False, low=0.0, high=0.65),
    ParameterSpec('ensemble_process', True, 'integrate the ensemble in a worker process (a '
                  'second core) one tick behind the mean model; false: in the node\'s process',
                  safe=False),
    ParameterSpec('seed', 0, 'seed of the ensemble (member j draws from the stream (seed, j))',
                  safe=False, low=0, high=2 ** 31 - 1),
    ParameterSpec('time_step_s', 0.005, 'model time step of the twin (s), the offline runs\' '
                  '5 ms; a tick takes the steps whose time the wall clock has reached (a step '
                  'longer than a tick waits for it); 10 ms halves the cost for 0.2 % error on '
                  'the stick-slip swing; 0: the configuration\'s', safe=False, low=0.0,
                  high=0.1),
    ParameterSpec('rate_hz', 100.0, 'tick rate of the wall-clock timer; a tick advances the '
                  'twin to the wall clock in model steps (never past it)', safe=False, low=1.0,
                  high=1000.0),
    ParameterSpec('fast', False, 'run as fast as possible and publish /clock (ignored with '
                  'use_sim_time, which follows an external /clock)', safe=False),
    ParameterSpec('duration_s', 0.0, 'stop after this much simulated time (0: run until '
                  'stopped)', safe=True, low=0.0, high=1e9),
    ParameterSpec('log_dir', 'runs', 'directory of the logs: each run is a rosbag2 bag '
                  '(a directory of MCAP splits and metadata.yaml) in it', safe=False),
    ParameterSpec('log_split_s', 300.0, 'log time (s) an MCAP split of the log holds at most '
                  '(rosbag2\'s max_bag_duration): only the split being written can be cut by '
                  'a crash or a full disk', safe=False, low=1.0, high=86400.0),
    ParameterSpec('log_state_rate_hz', 25.0, 'largest rate (per second of twin time) at '
                  'which the every-tick states (bit, top, wall contacts, stations, TF) are '
                  'logged; they are published every tick, everything else is logged as '
                  'published', safe=True, low=1.0, high=1000.0),
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
    ParameterSpec('top_drive_controller', '', 'stick-slip controller of the dynamic top drive: '
                  'stiff, soft_torque or impedance (empty: the model configuration\'s '
                  'top_drive.controller); at run time as the top_drive_controller command',
                  safe=True, choices=('', 'stiff', 'soft_torque', 'impedance')),
    ParameterSpec('top_drive_speed_max_rad_per_s', 30.0, 'largest accepted top-drive speed '
                  'command (rad/s)', safe=True, low=0.0, high=100.0),
    ParameterSpec('hook_load_min_n', 0.0, 'smallest accepted hook-load command (N)', safe=True,
                  low=0.0, high=1e8),
    ParameterSpec('hook_load_max_n', 5.0e6, 'largest accepted hook-load command (N)', safe=True,
                  low=0.0, high=1e8),
    ParameterSpec('top_drive_torque_limit_max_nm', 500.0e3, 'largest accepted motor torque '
                  'limit command of the dynamic top drive (N m)', safe=True, low=0.0, high=1e7),
    ParameterSpec('assimilation_enabled', False, 'correct the ensemble with the rig\'s '
                  'measurements (an ensemble Kalman filter, docs/ASSIMILATION.md): subscribe '
                  'to the sensor topics of assimilation_config, publish the estimated bit-rock '
                  'germ, the innovation statistics in the health report; the ensemble is the '
                  'analysed one, its germs drawn at the filter\'s prior_dispersion instead of '
                  'ensemble_dispersion (needs ensemble_members >= 2)', safe=False),
    ParameterSpec('assimilation_config', '', 'assimilation settings YAML: sensor topics, '
                  'delays, noise levels, the filter and its prior dispersion (empty: '
                  'config/assimilation.yaml; the ensemble\'s size and seed are the node\'s '
                  'parameters)', safe=False),
    ParameterSpec('assimilation_overrides', (), 'assimilation.KEY=VALUE overrides of the '
                  'assimilation settings, e.g. assimilation.filter.analysis_rate_hz=2.0',
                  safe=False),
)
BY_NAME = {p.name: p for p in PARAMETERS}


def _with_values(self, **changes):
    """Return a copy with ``changes`` (the node replaces its parameters on a change)."""
    return replace(self, **changes)


def _as_dict(self) -> dict:
    """{name: value} of every parameter."""
    return {f.name: getattr(self, f.name) for f in fields(self)}


def _from_values(cls, values) -> 'TwinParameters':
    """From {name: value} (defaults for missing names; lists become tuples)."""
    known = {name: tuple(value) if isinstance(value, list) else value
             for name, value in values.items() if name in BY_NAME}
    return cls(**known)


TwinParameters = make_dataclass(
    'TwinParameters',
    [(p.name, type(p.default), field(default=p.default)) for p in PARAMETERS],
    frozen=True, slots=True, kw_only=True,
    namespace={'__doc__': 'The twin node\'s parameters, one field per :data:`PARAMETERS` entry '
                          '(name, default; SI units as named). Frozen: a change at run time '
                          'makes a new object (:meth:`with_values`).',
               'with_values': _with_values, 'as_dict': _as_dict,
               'from_values': classmethod(_from_values)})
TwinParameters.__module__ = __name__


def unsafe_change_reason(name: str) -> str:
    """Why an unsafe parameter cannot change while the twin runs."""
    return (f'{name} cannot change while the twin runs: it sets up the model, the ensemble, '
            f'the clock or the log; restart the twin with the new value')


def markdown_table() -> str:
    """Return the parameter table of docs/ROS-INTERFACE.md."""
    def show(value):
        if isinstance(value, tuple):
            return '(empty list)' if not value else ', '.join(map(str, value))
        return repr(value)

    def span(p):
        if p.choices:
            return ', '.join(c if c else "'' (the configuration's)" for c in p.choices)
        number = (lambda x: str(x) if isinstance(x, int) else f'{x:g}')
        return '' if p.low is None else f'{number(p.low)} … {number(p.high)}'

    rows = ['| parameter | default | range | safe | meaning |', '|---|---|---|---|---|']
    rows += [f'| `{p.name}` | {show(p.default)} | {span(p)} | {"yes" if p.safe else "no"} | '
             f'{p.description} |' for p in PARAMETERS]
    return '\n'.join(rows)


# -- validation before the node starts (no rclpy) ------------------------------------------------
# rclpy refuses a value outside a parameter's range or of another type with a 31-line traceback
# (InvalidParameterValueException) from inside the node's constructor. The command line checks
# the same rules first and says what is wrong on one line.

ROS_PARAMETERS = {'use_sim_time': False, 'start_type_description_service': True}
"""Parameters every rclpy node declares itself (their defaults give their types)."""

_VALUE_OPTIONS = {'-r', '--remap', '--log-level', '--log-config-file', '-e', '--enclave',
                  '--log-file-name'}
"""ROS arguments that take a value (skipped when looking for parameters)."""


class ParameterError(ValueError):
    """
    A node parameter that the node would refuse.

    ``str()`` is one line naming where it was given (``origin``), the parameter and the problem.
    """

    def __init__(self, origin: str, name: str, message: str):
        where = ': '.join(part for part in (origin, name) if part)
        super().__init__(f'{where}: {message}' if where else message)
        self.origin = origin
        self.name = name
        self.message = message


def check_parameter(name: str, value, origin: str = ''):
    """
    Return ``value`` if the node accepts it for ``name``, else raise ParameterError.

    rclpy's rules: the default's type, no integer for a floating-point parameter, the range,
    the choices.
    """
    if name in ROS_PARAMETERS:
        if not isinstance(value, bool):
            raise ParameterError(origin, name, f'expected true or false, got {value!r}')
        return value
    spec = BY_NAME.get(name)
    if spec is None:
        raise ParameterError(origin, name, 'unknown parameter of the twin node (see '
                                           'docs/ROS-INTERFACE.md)')
    default = spec.default
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ParameterError(origin, name, f'expected true or false, got {value!r}')
    elif isinstance(default, int):
        if isinstance(value, bool) or not isinstance(value, int):
            raise ParameterError(origin, name, f'expected an integer, got {value!r}')
    elif isinstance(default, float):
        if isinstance(value, str):
            try:
                value = float(value)                     # rcl reads 'inf', 'nan' with strtod
            except ValueError:
                pass
        if isinstance(value, int) and not isinstance(value, bool):
            _check_range(spec, float(value), origin)
            raise ParameterError(origin, name, f'expected a floating-point number (ROS takes '
                                               f'no integer for it: write {value}.0), got '
                                               f'{value}')
        if not isinstance(value, float):
            raise ParameterError(origin, name, f'expected a number, got {value!r}')
        if value != value or value in (float('inf'), float('-inf')):
            raise ParameterError(origin, name, f'must be finite, got {value}')
    elif isinstance(default, str):
        if not isinstance(value, str):
            raise ParameterError(origin, name, f'expected a string, got {value!r}')
    elif isinstance(default, tuple):
        if not (isinstance(value, list) and all(isinstance(v, str) for v in value)):
            raise ParameterError(origin, name, f'expected a list of strings, got {value!r}')
    _check_range(spec, value, origin)
    if spec.choices and value not in spec.choices:
        raise ParameterError(origin, name, f'must be one of {spec.choices_text()}; got '
                                           f'{value!r}')
    return value


def _check_range(spec: ParameterSpec, value, origin: str) -> None:
    if spec.low is not None and not spec.low <= value <= spec.high:
        raise ParameterError(origin, spec.name, f'must lie in {spec.low:g} ... {spec.high:g}, '
                                                f'got {value:g}')


def parameters_from_ros_arguments(ros_args: list[str],
                                  node_name: str = 'drill_twin') -> list[tuple[str, str, object]]:
    """
    List (origin, name, value) of every parameter of the node in ``ros_args``.

    From --params-file files and -p/--param rules, in the order rcl applies them (the last
    one wins).

    Raises ParameterError for a file that cannot be read or a rule that cannot be parsed.
    """
    found = []
    tokens = iter(ros_args)
    for token in tokens:
        if token == '--params-file':
            path = next(tokens, None)
            if path is None:
                raise ParameterError('--params-file', '', 'a file name is needed')
            found.extend((path, name, value)
                         for name, value in parameters_in_file(path, node_name))
        elif token in ('-p', '--param'):
            rule = next(tokens, None)
            origin = f'--ros-args {token}'
            if rule is None or ':=' not in rule:
                raise ParameterError(origin, '', f'expected name:=value, got {rule!r}')
            name, text = rule.split(':=', 1)
            if ':' in name:                              # node:name applies to that node only
                target, name = name.split(':', 1)
                if target.strip('/').split('/')[-1] not in (node_name, '*', '**'):
                    continue
            found.append((origin, name, _parse_value(text, origin, name)))
        elif token in _VALUE_OPTIONS:
            next(tokens, None)
    return found


def parameters_in_file(path: str, node_name: str = 'drill_twin') -> list[tuple[str, object]]:
    """
    (name, value) of the node's parameters in a ROS 2 parameter file.

    Every ``ros__parameters`` mapping under the node's name, ``/**`` or ``/*`` (namespaces
    allowed), nested mappings flattened to dotted names.
    """
    from drill_twin.config import yaml_io
    import yaml

    try:
        with open(path, 'rb') as handle:
            content = handle.read(1 << 20)
        data = yaml_io.safe_load(content.decode('utf-8'))
    except OSError as error:
        raise ParameterError(path, '', f'cannot read: {error.strerror or error}') from None
    except UnicodeDecodeError:
        raise ParameterError(path, '', 'not a UTF-8 text file') from None
    except yaml.YAMLError as error:
        mark = getattr(error, 'problem_mark', None)
        where = f'line {mark.line + 1}' if mark is not None else ''
        raise ParameterError(path, where, 'YAML syntax error: ' + str(
            getattr(error, 'problem', None) or error).splitlines()[0]) from None
    if not isinstance(data, dict):
        raise ParameterError(path, '', 'expected a mapping of node names to ros__parameters')
    found = []

    def walk(mapping, names):
        for key, value in mapping.items():
            if key == 'ros__parameters':
                target = '/'.join(names).strip('/').split('/')[-1] if names else ''
                if target in (node_name, '*', '**'):
                    if not isinstance(value, dict):
                        raise ParameterError(path, '/'.join(names), 'ros__parameters must be '
                                                                    'a mapping')
                    found.extend(_flatten(value, ''))
            elif isinstance(value, dict):
                walk(value, names + [str(key)])

    walk(data, [])
    return found


def validate_ros_arguments(ros_args: list[str], node_name: str = 'drill_twin') -> dict:
    """
    Return the parameters the node will start with (defaults, then ``ros_args`` in order).

    Each is checked by :func:`check_parameter`; raises ParameterError on the first bad one.
    """
    values = {spec.name: (list(spec.default) if isinstance(spec.default, tuple)
                          else spec.default) for spec in PARAMETERS}
    for origin, name, value in parameters_from_ros_arguments(ros_args, node_name):
        values[name] = check_parameter(name, value, origin)
    if values['hook_load_min_n'] > values['hook_load_max_n']:
        raise ParameterError('parameters', 'hook_load_min_n',
                             f'{values["hook_load_min_n"]:g} exceeds hook_load_max_n '
                             f'({values["hook_load_max_n"]:g})')
    return values


def model_overrides(values) -> list[str]:
    """
    Return the ``--set`` items the node applies to its model configuration.

    ``time_step_s`` (when > 0) first, ``top_drive_controller`` (when set), then
    ``model_overrides`` (``values``: a dict or TwinParameters).
    """
    if not isinstance(values, dict):
        values = values.as_dict()
    overrides = [item for item in (values.get('model_overrides') or []) if item]
    if values.get('top_drive_controller'):
        overrides.insert(0, f'top_drive.controller={values["top_drive_controller"]}')
    if values.get('time_step_s', 0) > 0:
        overrides.insert(0, f'integration.time_step_s={values["time_step_s"]!r}')
    return overrides


def _parse_value(text: str, origin: str, name: str):
    from drill_twin.config import yaml_io
    import yaml

    try:
        return yaml_io.safe_load(text)
    except yaml.YAMLError:
        raise ParameterError(origin, name, f'cannot parse the value {text!r}') from None


def _flatten(mapping: dict, prefix: str):
    for key, value in mapping.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            yield from _flatten(value, name + '.')
        else:
            yield name, value
