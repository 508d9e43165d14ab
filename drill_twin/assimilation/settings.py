"""
The ``assimilation:`` settings (config/assimilation.yaml) as validated frozen dataclasses.

The rig emulator and the filter read the same section: the rig takes the sensors' rates,
delays, noise and bias as the truth's; the filter takes them as what it assumes of the
sensors (its noise covariance R), so the filter's file (or ``--set``) may differ from the
rig's: a bias the filter is not told of, a noise it overstates.

Loaded by :func:`load_assimilation`: the shipped file, an optional file of the user's merged
over it, then ``--set assimilation.KEY=VALUE`` overrides; a bad value raises
:class:`~drill_twin.config.loader.ConfigError` naming the key (one line).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Literal

import numpy as np

from drill_twin.config.loader import (ConfigError, _build, _BuildError, _read_yaml,
                                      apply_override, merge)
from drill_twin.config.paths import config_directory
from drill_twin.config.schema import ConfigValueError
from drill_twin.uncertainty.germ import MAX_DISPERSION

SECTION = 'assimilation'
DEFAULT_FILE = 'assimilation.yaml'
BLOCKS = ('axial', 'torsional', 'bending_y', 'bending_z')

Method = Literal['etkf', 'enkf']
Parameters = Literal['germ', 'law', 'none']
Bounds = Literal['student_t', 'percentile']
Localisation = Literal['none', 'motion']
HoleRatePrediction = Literal['own_drilling', 'steady_law']


def _check(condition: bool, key: str, message: str, value) -> None:
    if not condition:
        raise ConfigValueError(key, f'{message}, got {value!r}')


@dataclass(frozen=True, slots=True, kw_only=True)
class Channel:
    """
    One measured quantity.

    Noise standard deviation noise_std + noise_relative |value| (combined in quadrature; SI
    units of the quantity) and a constant bias (SI): the rig's sensor adds it to its readings;
    the filter subtracts it from them (a known calibration offset; 0: none known).
    bias_prior_std (SI, filter only): the standard deviation of the prior of a constant bias
    beyond ``bias`` that the filter estimates with the state, one per member (an augmented
    parameter; 0: not estimated); bias_walk_std (SI, filter only): the standard deviation of
    a centred random change of each member's bias after each analysis (None: the filter's
    ``parameter_walk_std`` times ``bias_prior_std``). topic: None (the channel comes in its
    sensor's sensor_msgs/JointState), or a topic of its own carrying it as std_msgs/Float64
    (unstamped: taken as sampled when received less its sensor's ``delay_s``; the rig
    emulator then writes it there and not in the JointState).
    """

    noise_std: float
    noise_relative: float = 0.0
    bias: float = 0.0
    bias_prior_std: float = 0.0
    bias_walk_std: float | None = None
    topic: str | None = None

    def __post_init__(self):
        _check(self.noise_std >= 0, 'noise_std', 'must be >= 0', self.noise_std)
        _check(self.noise_relative >= 0, 'noise_relative', 'must be >= 0',
               self.noise_relative)
        _check(math.isfinite(self.bias), 'bias', 'must be finite', self.bias)
        _check(math.isfinite(self.bias_prior_std) and self.bias_prior_std >= 0,
               'bias_prior_std', 'must be >= 0', self.bias_prior_std)
        _check(self.bias_walk_std is None or (math.isfinite(self.bias_walk_std)
                                              and self.bias_walk_std >= 0),
               'bias_walk_std', 'must be >= 0 (or null)', self.bias_walk_std)
        _check(self.topic is None or (isinstance(self.topic, str) and self.topic.startswith('/')),
               'topic', 'must be an absolute topic name (or null)', self.topic)

    def std(self, value):
        """Return the noise standard deviation at ``value`` (same shape)."""
        return np.hypot(self.noise_std, self.noise_relative * np.abs(value))


@dataclass(frozen=True, slots=True, kw_only=True)
class Channels:
    """The channels a rig measures (units: rad/s, N m, N, m)."""

    top_speed: Channel
    top_torque: Channel
    hook_load: Channel
    block_position: Channel
    bit_speed: Channel
    torque_on_bit: Channel
    weight_on_bit: Channel


@dataclass(frozen=True, slots=True, kw_only=True)
class Sensor:
    """
    A sensor's messages.

    On ``topic`` at ``rate_hz``, each arriving ``delay_s`` after the instant it samples (its
    header stamp): 0 at the surface, seconds for mud-pulse data.
    """

    topic: str
    rate_hz: float
    delay_s: float = 0.0

    def __post_init__(self):
        _check(self.topic.startswith('/'), 'topic', 'must be an absolute topic name',
               self.topic)
        _check(math.isfinite(self.rate_hz) and self.rate_hz > 0, 'rate_hz', 'must be > 0',
               self.rate_hz)
        _check(self.delay_s >= 0, 'delay_s', 'must be >= 0', self.delay_s)


@dataclass(frozen=True, slots=True, kw_only=True)
class Sensors:
    """
    The rig's sensors: top drive, hook and downhole.

    top_drive: surface speed and torque (sensor_msgs/JointState 'top_drive'); hook: hook load
    and block position (JointState 'hook', effort and position); downhole: bit speed, TOB and WOB
    (JointState 'bit_rotation' velocity/effort, 'bit_axial' effort).
    """

    top_drive: Sensor
    hook: Sensor
    downhole: Sensor


SENSOR_OF = {'top_speed': 'top_drive', 'top_torque': 'top_drive', 'hook_load': 'hook',
             'block_position': 'hook', 'bit_speed': 'downhole', 'torque_on_bit': 'downhole',
             'weight_on_bit': 'downhole'}
"""Which sensor carries each channel."""


@dataclass(frozen=True, slots=True, kw_only=True)
class Filter:
    """
    The ensemble filter.

    method: etkf or enkf; members: N (>= 2); inflation: multiplicative, of the anomalies at
    every analysis (>= 1); relaxation: RTPP weight of the forecast anomalies in the analysed
    ones ([0, 1)); analysis_rate_hz: analyses per second of model time (the
    measurements that arrived since the last one are used together); measurements: the
    channels it uses; blocks: the reduced-coordinate blocks it analyses (the others are left
    as each member has them: localisation by variable); parameters: germ (the bit-rock germ
    as an augmented state), law (the germ and the log-factors of a1 ... a5 of each member's
    law) or none; prior_dispersion: delta of the members' initial germs;
    law_prior_log_std: standard deviation of the members' initial log-factors of a1 ... a5
    (parameters 'law'; 0.15: a factor of 1.3 at 1.75 sigma);
    bounds: how the 95 % bounds are drawn from the members (bounds.interval);
    model_error_bit_speed_rad_per_s: additive inflation for model error, the standard
    deviation of a centred random change of each member's bit speed after each analysis
    (rad/s, 0: none); parameter_walk_std: additive inflation of the augmented parameters,
    the standard deviation of a centred random change of each of their coordinates (log
    factors, germ coordinates) after each analysis (0: none; it keeps a static parameter's
    spread from collapsing); parameter_inflation, parameter_relaxation: the multiplicative
    inflation and the RTPP weight of the augmented parameters' anomalies (None: the state's
    ``inflation`` and ``relaxation``; by default no inflation: a parameter has no dynamics
    of its own, so inflating it at every analysis compounds where the data say little,
    docs/ASSIMILATION.md); hole_rate_window_s: the length of the windows over which the
    block's least-squares slope is compared with each member's own drilling (s; null: off;
    :mod:`.hole_rate`: it gives the law's parameters the hole's rate, which the block position
    analysed sample by sample hands to the state); hole_rate_prediction: what a member
    predicts of a window's slope: own_drilling (the depth its law drilled in its steps) or
    steady_law (its law's steady ROP at its mean bit speed and WOB over the window);
    increment_duration_s: the analysis's increment (state and parameters) is added in equal
    parts at every step over this much model time (an incremental analysis update: an
    instantaneous change of the bit's speed or law moves the WOB at once through the law's
    stiff dependence on them, and the members ring; docs/ASSIMILATION.md; 0: at once; less
    than an analysis interval); localisation: none (every measurement
    analyses the whole state) or motion (the axial block's coordinates, rates and the hole's
    offset are analysed with the axial channels only, the torsional block's with the torsional
    ones, :data:`~drill_twin.assimilation.measurements.MOTION_OF`; the parameters and any
    bending block with all: a member's axial state then never moves on a torque's sampling
    correlation); seed: of the germs and the perturbations.
    """

    method: Method = 'etkf'
    members: int = 64
    inflation: float = 1.0
    relaxation: float = 0.5
    analysis_rate_hz: float = 1.0
    measurements: tuple[str, ...] = ('top_torque', 'block_position')
    blocks: tuple[str, ...] = ('axial', 'torsional')
    parameters: Parameters = 'law'
    prior_dispersion: float = 0.2
    law_prior_log_std: float = 0.15
    bounds: Bounds = 'student_t'
    model_error_bit_speed_rad_per_s: float = 0.0
    parameter_walk_std: float = 0.001
    parameter_inflation: float | None = 1.0
    parameter_relaxation: float | None = None
    hole_rate_window_s: float | None = None
    hole_rate_prediction: HoleRatePrediction = 'own_drilling'
    increment_duration_s: float = 0.05
    localisation: Localisation = 'none'
    seed: int = 0

    def __post_init__(self):
        _check(self.members >= 2, 'members', 'must be >= 2', self.members)
        _check(self.inflation >= 1, 'inflation', 'must be >= 1', self.inflation)
        _check(0 <= self.relaxation < 1, 'relaxation', 'must be in [0, 1)', self.relaxation)
        _check(self.parameter_inflation is None or self.parameter_inflation >= 1,
               'parameter_inflation', 'must be >= 1 (or null: the state\'s)',
               self.parameter_inflation)
        _check(self.parameter_relaxation is None or 0 <= self.parameter_relaxation < 1,
               'parameter_relaxation', 'must be in [0, 1) (or null: the state\'s)',
               self.parameter_relaxation)
        _check(self.analysis_rate_hz > 0, 'analysis_rate_hz', 'must be > 0',
               self.analysis_rate_hz)
        for name in self.measurements:
            _check(name in SENSOR_OF, 'measurements',
                   f'must name channels among {", ".join(SENSOR_OF)}', name)
        _check(len(self.measurements) > 0, 'measurements', 'must name a channel',
               self.measurements)
        for name in self.blocks:
            _check(name in BLOCKS, 'blocks', f'must be among {", ".join(BLOCKS)}', name)
        _check(0 <= self.prior_dispersion < MAX_DISPERSION, 'prior_dispersion',
               f'must be in [0, {MAX_DISPERSION:.4f})', self.prior_dispersion)
        _check(self.seed >= 0, 'seed', 'must be >= 0', self.seed)
        _check(0 <= self.parameter_walk_std <= 0.1, 'parameter_walk_std', 'must be in [0, 0.1]',
               self.parameter_walk_std)
        _check(0 <= self.law_prior_log_std <= 1, 'law_prior_log_std', 'must be in [0, 1]',
               self.law_prior_log_std)
        _check(self.model_error_bit_speed_rad_per_s >= 0, 'model_error_bit_speed_rad_per_s',
               'must be >= 0', self.model_error_bit_speed_rad_per_s)
        _check(self.hole_rate_window_s is None or (math.isfinite(self.hole_rate_window_s)
                                                   and self.hole_rate_window_s > 0),
               'hole_rate_window_s', 'must be > 0 (or null: off)', self.hole_rate_window_s)
        _check(self.hole_rate_window_s is None or 'block_position' in self.measurements,
               'hole_rate_window_s', 'needs block_position among the measurements',
               self.measurements)
        _check(math.isfinite(self.increment_duration_s)
               and 0 <= self.increment_duration_s < 1.0 / self.analysis_rate_hz,
               'increment_duration_s', 'must be >= 0 and shorter than an analysis interval '
               f'(1 / analysis_rate_hz = {1.0 / self.analysis_rate_hz:g} s)',
               self.increment_duration_s)
        _check(self.model_error_bit_speed_rad_per_s == 0 or 'torsional' in self.blocks,
               'model_error_bit_speed_rad_per_s', 'needs the torsional block analysed',
               self.blocks)


@dataclass(frozen=True, slots=True, kw_only=True)
class SetPoint:
    """
    A change of the commands at ``time_s`` (s).

    The top-drive speed (Hz) and/or the hook load, as a change from the initial one (N, > 0
    lifts: less weight on bit).
    """

    time_s: float
    top_drive_speed_hz: float | None = None
    hook_load_change_n: float | None = None

    def __post_init__(self):
        _check(self.time_s >= 0, 'time_s', 'must be >= 0', self.time_s)
        if self.top_drive_speed_hz is not None:
            _check(self.top_drive_speed_hz > 0, 'top_drive_speed_hz', 'must be > 0',
                   self.top_drive_speed_hz)


@dataclass(frozen=True, slots=True, kw_only=True)
class Rig:
    """
    The rig emulator.

    Its schedule of set-points, the rate of the true downhole state it records for scoring (Hz)
    and the seed of its sensor noise.
    """

    schedule: tuple[SetPoint, ...] = ()
    truth_rate_hz: float = 20.0
    seed: int = 1

    def __post_init__(self):
        _check(self.truth_rate_hz > 0, 'truth_rate_hz', 'must be > 0', self.truth_rate_hz)
        _check(self.seed >= 0, 'seed', 'must be >= 0', self.seed)
        times = [point.time_s for point in self.schedule]
        _check(times == sorted(times), 'schedule', 'must be in time order', times)


BIAS_COUNTERPART = {'top_torque': 'torque_on_bit', 'torque_on_bit': 'top_torque'}
"""The channels whose sensor bias the filter can estimate, and the channel that must be
measured with each. In steady rotation the surface torque is the TOB plus the string's drag,
and the law's TOB is a4 DOC + a5 with a5 a constant: a constant offset of one torque sensor
reads like a change of a5 unless the torque at the other end is measured too, or the law is
not estimated (``parameters: none``). Measured (docs/ASSIMILATION.md): the law estimated,
without the TOB, the estimate ended at 162 N m, bounds 138-183, for a 100 N m bias. Other
channels' biases are refused: their observability is not established."""


@dataclass(frozen=True, slots=True, kw_only=True)
class AssimilationConfig:
    """The whole ``assimilation:`` section."""

    filter: Filter
    sensors: Sensors
    channels: Channels
    rig: Rig
    source: str = '<defaults>'

    def __post_init__(self):
        taken = [getattr(self.sensors, name).topic for name in ('top_drive', 'hook', 'downhole')]
        for name, topic in self.scalar_topics().items():   # a topic carries one thing
            _check(topic not in taken, f'channels.{name}.topic',
                   "must be a topic of the channel's own", topic)
            taken.append(topic)
        for channel in self.estimated_bias_channels():
            other = BIAS_COUNTERPART.get(channel)
            _check(other is not None, f'channels.{channel}.bias_prior_std',
                   'a bias is estimated for ' + ' or '.join(BIAS_COUNTERPART) + ' only',
                   self.channel(channel).bias_prior_std)
            _check(other in self.filter.measurements or self.filter.parameters == 'none',
                   f'channels.{channel}.bias_prior_std',
                   f'needs {other} among filter.measurements, or filter.parameters none '
                   '(the law estimated, its bias is not observable)',
                   self.channel(channel).bias_prior_std)

    def channel(self, name: str) -> Channel:
        return getattr(self.channels, name)

    def sensor_of(self, name: str) -> Sensor:
        return getattr(self.sensors, SENSOR_OF[name])

    def scalar_topics(self) -> dict[str, str]:
        """Return {channel: topic} of the channels carried as std_msgs/Float64 on their own."""
        return {name: self.channel(name).topic for name in SENSOR_OF
                if self.channel(name).topic is not None}

    def estimated_bias_channels(self) -> tuple[str, ...]:
        """Return the filter's channels whose bias it estimates (``bias_prior_std`` > 0)."""
        return tuple(c for c in self.filter.measurements
                     if self.channel(c).bias_prior_std > 0)


def default_path() -> Path:
    return config_directory() / DEFAULT_FILE


def load_assimilation(path: str | Path | None = None,
                      overrides: Iterable[str] = ()) -> AssimilationConfig:
    """
    Return the section from the shipped file, with ``path`` and ``overrides`` merged over it.

    ``overrides`` are ``assimilation.KEY=VALUE`` items; others are ignored: they belong to the
    model.
    """
    defaults = default_path()
    raw = _section(_read_yaml(defaults), str(defaults))
    source = str(defaults)
    if path is not None:
        source = str(path)
        raw = merge(raw, _section(_read_yaml(Path(path)), source))
    ours = [item for item in overrides if item.startswith(SECTION + '.')]
    for item in ours:
        raw = apply_override({SECTION: raw}, item)[SECTION]
    try:
        built = _build(AssimilationConfig, raw, SECTION, extra={'source': source})
    except _BuildError as error:
        where = '--set' if any(item.split('=', 1)[0].strip() == error.key
                               or error.key.startswith(item.split('=', 1)[0].strip() + '.')
                               for item in ours) else source
        raise ConfigError(where, error.key, error.message) from None
    return built


def model_overrides(overrides: Iterable[str]) -> list[str]:
    """Return the ``--set`` items that are not ours (the model's)."""
    return [item for item in overrides if not item.startswith(SECTION + '.')]


def _section(raw: dict, source: str) -> dict:
    if set(raw) != {SECTION}:
        extra = sorted(set(raw) - {SECTION})
        raise ConfigError(source, extra[0] if extra else SECTION,
                          f'expected one top-level key {SECTION!r}' if extra else 'missing')
    section = raw[SECTION]
    if not isinstance(section, dict):
        raise ConfigError(source, SECTION, 'expected a mapping')
    return section
