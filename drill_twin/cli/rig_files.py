"""
The files of the rig emulator and the offline filter, in model time from 0 (ns).

RIG.mcap, written by ``drill-twin rig`` (:func:`write_rig_log`) and read by ``drill-twin
assimilate`` (:func:`read_rig_log`, no rclpy: the CDR is decoded here), holds:

- the sensors of ``assimilation.sensors`` (sensor_msgs/JointState, header stamp = when
  sampled, log time = when received: later by the sensor's delay): '/rig/top_drive' joint
  'top_drive' (velocity = surface speed rad/s, effort = torque N m); '/rig/hook' joint 'hook'
  (position = block position m down, effort = hook load N); '/rig/downhole' joints
  'bit_rotation' (velocity = bit speed, effort = TOB) and 'bit_axial' (effort = WOB; its
  velocity is NaN: not measured); a channel with a topic of its own
  (``assimilation.channels.<c>.topic``) is written there instead, as std_msgs/Float64 at
  its arrival (unstamped), and its JointState field is NaN;
- the commands it was driven with on the twin's command topics
  (/drill_twin/cmd/top_drive_speed, /drill_twin/cmd/hook_load, std_msgs/Float64);
- the true downhole state for scoring on topics of its own: /rig/truth/bit_state
  (JointState 'bit_axial': depth, ROP, WOB; 'bit_rotation': angle, speed, TOB) and
  /rig/truth/hole_depth (std_msgs/Float64, m);
- a metadata record 'drill_twin_rig' (duration, germ, the truth's configuration as JSON).

EST.mcap, written by ``drill-twin assimilate`` (:func:`write_estimate`), holds at the truth's
instants (or at the analysis instants without a truth):

- /drill_twin/assimilation/bit_state/{mean,lower,upper}: the filter's bit speed (JointState
  'bit_rotation' velocity, rad/s): ensemble mean and 95 % bounds (assimilation.filter.bounds);
- /drill_twin/assimilation/open_loop/bit_state/{mean,lower,upper}: the same ensemble without
  analysis;
- /drill_twin/assimilation/germ/{mean,lower,upper}: the estimated bit-rock germ (std_msgs/
  Float64MultiArray [G11, G12, G22]) after each analysis, and with parameters 'law'
  /drill_twin/assimilation/law/{mean,lower,upper}: the factors of the law's a1 ... a5, and
  /drill_twin/assimilation/bias/{mean,lower,upper} the estimated sensor biases (SI, one
  dimension labelled with their channels) when a channel has ``bias_prior_std`` > 0;
- /diagnostics: per analysis the normalised innovation squared and its count of
  measurements (diagnostic_msgs/DiagnosticArray, name 'drill_twin: assimilation');
- the rig log's truth (/rig/truth/bit_state), when it has one.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from drill_twin import interface as itf
from drill_twin.assimilation.measurements import joint_state_fields, values_from_joint_state
from drill_twin.assimilation.rig_log import RigLog, SensorSamples, Truth
from drill_twin.cli.common import UsageError
from drill_twin.recording import cdr
from drill_twin.recording.mcap_log import McapLog
from drill_twin.recording.message_types import import_message_class
from drill_twin.recording.reader import iter_raw, NotMcapError, read_metadata

TRUTH_BIT = itf.RIG_TRUTH_BIT_STATE
TRUTH_HOLE = '/rig/truth/hole_depth'
METADATA = 'drill_twin_rig'
PREFIX = itf.ASSIMILATION_PREFIX


def _ns(seconds: float) -> int:
    return int(round(seconds * 1e9))


def _stamp(message, t_ns: int) -> None:
    message.header.stamp.sec = t_ns // 1_000_000_000
    message.header.stamp.nanosec = t_ns % 1_000_000_000


def _joint_state(t_ns: int, names, position=(), velocity=(), effort=()):
    """Return a sensor_msgs/JointState stamped ``t_ns`` (ns), its values as floats."""
    message = import_message_class('sensor_msgs/msg/JointState')()
    _stamp(message, t_ns)
    message.name = list(names)
    message.position = [float(v) for v in position]
    message.velocity = [float(v) for v in velocity]
    message.effort = [float(v) for v in effort]
    return message


def _truth_states(truth: Truth) -> list[tuple[int, str, object]]:
    """(ns, topic, message) of the true bit state at each of its instants."""
    return [(_ns(time_s), TRUTH_BIT, _joint_state(
        _ns(time_s), [itf.BIT_AXIAL, itf.BIT_ROTATION],
        [truth.bit_depth_m[k], truth.bit_angle_rad[k]],
        [truth.rop_m_per_s[k], truth.bit_speed_rad_per_s[k]],
        [truth.weight_on_bit_n[k], truth.torque_on_bit_nm[k]]))
        for k, time_s in enumerate(truth.time_s)]


def write_rig_log(path, log: RigLog, settings, metadata: dict[str, str]) -> None:
    """Write a RigLog (see the module docstring for the layout)."""
    float64 = import_message_class('std_msgs/msg/Float64')
    messages = []                                     # (log time ns, topic, message)
    scalar_topics = settings.scalar_topics()         # these channels: Float64 of their own
    joint_states = set()
    for name, samples in log.sensors.items():
        topic = getattr(settings.sensors, name).topic
        v = samples.values
        carried = [c for c in v if c not in scalar_topics]
        for k, (stamp, arrival) in enumerate(zip(samples.stamp_s, samples.arrival_s)):
            for channel in v:
                if channel in scalar_topics:
                    messages.append((_ns(arrival), scalar_topics[channel],
                                     float64(data=float(v[channel][k]))))
            if carried:
                fields = joint_state_fields(name, {c: v[c][k] for c in carried})
                messages.append((_ns(arrival), topic, _joint_state(_ns(stamp), *fields)))
                joint_states.add(name)
    for topic, commands in ((itf.CMD_TOP_DRIVE_SPEED, log.speed_commands),
                            (itf.CMD_HOOK_LOAD, log.hook_commands)):
        for time_s, value in commands:
            messages.append((_ns(time_s), topic, float64(data=float(value))))
    truth = log.truth
    if truth is not None:
        for state, depth_m in zip(_truth_states(truth), truth.hole_depth_m):
            messages += [state, (state[0], TRUTH_HOLE, float64(data=float(depth_m)))]
    messages.sort(key=lambda item: item[0])
    with McapLog(path) as out:
        for name in sorted(joint_states):
            out.add_topic(getattr(settings.sensors, name).topic, 'sensor_msgs/msg/JointState')
        for channel in sorted(c for s in log.sensors.values() for c in s.values
                              if c in scalar_topics):
            out.add_topic(scalar_topics[channel], 'std_msgs/msg/Float64')
        out.add_topic(itf.CMD_TOP_DRIVE_SPEED, 'std_msgs/msg/Float64', itf.COMMAND_QOS)
        out.add_topic(itf.CMD_HOOK_LOAD, 'std_msgs/msg/Float64', itf.COMMAND_QOS)
        if truth is not None:
            out.add_topic(TRUTH_BIT, 'sensor_msgs/msg/JointState')
            out.add_topic(TRUTH_HOLE, 'std_msgs/msg/Float64')
        out.add_metadata(METADATA, metadata)
        for t_ns, topic, message in messages:
            out.write(topic, message, t_ns)


def read_rig_log(path, settings) -> RigLog:
    """
    Return the RigLog of a log with the sensor topics of ``settings`` (no rclpy: CDR decoded here).

    Raises UsageError naming the problem (one line).
    """
    sensor_of_topic = {getattr(settings.sensors, name).topic: name
                       for name in ('top_drive', 'hook', 'downhole')}
    channel_of_topic = {topic: channel for channel, topic in settings.scalar_topics().items()}
    records = _read_records(path, sensor_of_topic, channel_of_topic)
    metadata = read_metadata(path)
    duration = float(metadata.get(METADATA, {}).get('duration_s', records.last_ns * 1e-9))
    sensors = _sensor_samples(path, records.sensors, set(records.scalars))
    scalars = {channel: _scalar_samples(items, settings.sensor_of(channel).delay_s, channel)
               for channel, items in records.scalars.items() if items}
    if not sensors and not scalars:
        raise UsageError(f'{path}: no measurement topics ('
                         + ', '.join([*sensor_of_topic, *channel_of_topic]) + ')')
    if not records.speed or not records.hook:
        raise UsageError(f'{path}: no commands on {itf.CMD_TOP_DRIVE_SPEED} and '
                         f'{itf.CMD_HOOK_LOAD}')
    return RigLog(duration_s=duration, sensors=sensors,
                  speed_commands=np.array(records.speed), hook_commands=np.array(records.hook),
                  truth=_truth(records.truth, records.hole), metadata=metadata.get(METADATA, {}),
                  scalars=scalars)


@dataclass
class _RigRecords:
    """The rows of a rig log as read, by topic kind (times in ns unless named _s)."""

    sensors: dict[str, list]
    """{sensor: [(stamp, log time, position, velocity, effort)]}."""
    scalars: dict[str, list]
    """{channel: [(log time, value)]}: the channels on topics of their own."""
    speed: list = field(default_factory=list)
    """[(log time s, top-drive speed command rad/s)]."""
    hook: list = field(default_factory=list)
    """[(log time s, hook-load command N)]."""
    truth: list = field(default_factory=list)
    """[(stamp s, bit speed, angle, ROP, TOB, WOB, depth)]."""
    hole: dict = field(default_factory=dict)
    """{log time: hole depth m}."""
    last_ns: int = 0


def _read_records(path, sensor_of_topic: dict, channel_of_topic: dict) -> _RigRecords:
    """Decode every message of the rig log's topics (UsageError if one is malformed)."""
    records = _RigRecords({name: [] for name in sensor_of_topic.values()},
                          {channel: [] for channel in channel_of_topic.values()})
    try:
        for _, channel, record in iter_raw(path):
            topic = channel.topic
            records.last_ns = max(records.last_ns, record.log_time)
            try:
                _add_record(records, topic, record, sensor_of_topic, channel_of_topic)
            except (ValueError, IndexError) as error:
                raise UsageError(f'{path}: a message on {topic} is malformed ({error})') from None
    except (FileNotFoundError, NotMcapError) as error:
        raise UsageError(str(error)) from None
    return records


def _add_record(records: _RigRecords, topic: str, record, sensor_of_topic: dict,
                channel_of_topic: dict) -> None:
    if topic in sensor_of_topic:
        stamp, position, velocity, effort = cdr.joint_state(record.data)
        records.sensors[sensor_of_topic[topic]].append(
            (stamp, record.log_time, position, velocity, effort))
    elif topic in channel_of_topic:
        records.scalars[channel_of_topic[topic]].append(
            (record.log_time, cdr.float64(record.data)))
    elif topic == itf.CMD_TOP_DRIVE_SPEED:
        records.speed.append((record.log_time * 1e-9, cdr.float64(record.data)))
    elif topic == itf.CMD_HOOK_LOAD:
        records.hook.append((record.log_time * 1e-9, cdr.float64(record.data)))
    elif topic == TRUTH_BIT:
        stamp, position, velocity, effort = cdr.joint_state(record.data)
        records.truth.append((stamp * 1e-9, velocity[1], position[1], velocity[0],
                              effort[1], effort[0], position[0]))
    elif topic == TRUTH_HOLE:
        records.hole[record.log_time] = cdr.float64(record.data)


def _sensor_samples(path, rows: dict[str, list], own_topic: set) -> dict[str, SensorSamples]:
    """Return each sensor's samples by stamp, its channels on topics of their own left out."""
    sensors = {}
    for name, items in rows.items():
        if not items:
            continue
        items.sort(key=lambda item: item[0])
        stamp = np.array([i[0] for i in items]) * 1e-9
        arrival = np.array([i[1] for i in items]) * 1e-9
        try:
            read = [values_from_joint_state(name, None, *i[2:]) for i in items]
            values = {c: [r[c] for r in read] for c in read[0] if c not in own_topic}
        except (ValueError, KeyError):
            raise UsageError(f'{path}: {name} messages lack their fields (see drill-twin rig '
                             '--help for the layout)') from None
        sensors[name] = SensorSamples(stamp, arrival,
                                      {k: np.asarray(v, dtype=float) for k, v in values.items()})
    return sensors


def _scalar_samples(items: list, delay_s: float, channel: str) -> SensorSamples:
    """Return a channel's samples on a topic of its own: unstamped, so received less the delay."""
    arrival = np.array([i[0] for i in sorted(items)]) * 1e-9
    return SensorSamples(arrival - delay_s, arrival,
                         {channel: np.array([i[1] for i in sorted(items)], dtype=float)})


def _truth(rows: list, hole: dict) -> Truth | None:
    """Return the true downhole state at its stamps, with the hole depth logged with it."""
    if not rows:
        return None
    columns = np.array(rows, dtype=float).T
    holes = np.array([hole.get(_ns(t), math.nan) for t in columns[0]])
    return Truth(columns[0], columns[1], columns[2], columns[3], columns[4], columns[5],
                 columns[6], holes)


def write_estimate(path, estimate, log: RigLog, method: str = 'student_t', log_path='') -> None:
    """EST.mcap (module docstring); ``log_path``: the rig log's, for the metadata record."""
    a = estimate.arrays()
    filtered, open_loop = estimate.bounds('filtered', method), estimate.bounds('open_loop', method)
    messages = []
    for k, time_s in enumerate(a['time_s']):
        t = _ns(time_s)
        for prefix, values in ((itf.ASSIMILATION_BIT_STATE, filtered[k]),
                               (itf.ASSIMILATION_OPEN_LOOP_BIT_STATE, open_loop[k])):
            for column, name in enumerate(('mean', 'lower', 'upper')):
                messages.append((t, f'{prefix}/{name}', _joint_state(
                    t, [itf.BIT_ROTATION], velocity=[values[column]])))
    for k, time_s in enumerate(a['analysis_time_s']):
        messages += _analysis_messages(_ns(time_s), a, k, estimate.bias_channels)
    if log.truth is not None:
        messages += _truth_states(log.truth)
    messages.sort(key=lambda item: item[0])
    with McapLog(path) as out:
        out.add_metadata(itf.ESTIMATE_METADATA, {'clock_epoch_ns': '0', 'log': str(log_path)})
        for t_ns, topic, message in messages:
            kind = type(message).__module__.split('.')[0] + '/msg/' + type(message).__name__
            out.add_topic(topic, kind)
            out.write(topic, message, t_ns)


def _analysis_messages(t: int, a: dict, k: int, bias_channels: tuple) -> list:
    """(ns, topic, message) of analysis ``k``: the estimated parameters and its diagnostics."""
    array = import_message_class('std_msgs/msg/Float64MultiArray')
    dimension = import_message_class('std_msgs/msg/MultiArrayDimension')
    key_value = import_message_class('diagnostic_msgs/msg/KeyValue')
    messages = []
    for estimated in ('germ', 'law'):           # what the filter estimates (not NaN)
        if a[f'{estimated}_mean'].size and np.all(np.isfinite(a[f'{estimated}_mean'][k])):
            for name in ('mean', 'lower', 'upper'):
                messages.append((t, f'{PREFIX}/{estimated}/{name}', array(
                    data=[float(v) for v in a[f'{estimated}_{name}'][k]])))
    if bias_channels:                           # labelled by channel, as the twin's
        for name in ('mean', 'lower', 'upper'):
            message = array(data=[float(v) for v in a[f'bias_{name}'][k]])
            message.layout.dim = [dimension(label=','.join(bias_channels),
                                            size=len(bias_channels), stride=len(bias_channels))]
            messages.append((t, f'{PREFIX}/bias/{name}', message))
    status = import_message_class('diagnostic_msgs/msg/DiagnosticStatus')(
        level=b'\x00', name='drill_twin: assimilation', message='analysis',
        hardware_id='drill_twin')
    status.values = [key_value(key='nis', value=f'{a["nis"][k]:.6g}'),
                     key_value(key='measurements', value=str(int(a['measurements'][k])))]
    message = import_message_class('diagnostic_msgs/msg/DiagnosticArray')()
    _stamp(message, t)
    message.status = [status]
    messages.append((t, itf.DIAGNOSTICS, message))
    return messages
