"""
``drill-twin rig``: the rig emulator (issue 15).

The model as the truth, logged as a rig measures it.

RIG.mcap holds (model time from 0, in ns):

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
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from drill_twin import interface as itf
from drill_twin.cli.common import (UsageError, add_config_arguments, blamed,
                                   positive_seconds)
from drill_twin.cli.progress import ProgressBar

TRUTH_BIT = itf.RIG_TRUTH_BIT_STATE
TRUTH_HOLE = '/rig/truth/hole_depth'
METADATA = 'drill_twin_rig'


def add_parser(subparsers) -> None:
    parser = subparsers.add_parser(
        'rig', help='rig emulator: a log of what a rig measures, with the truth',
        description='Run the model as the truth under a schedule of set-points (default: the '
                    'paper\'s operating point, then a speed and a hook-load change) and write '
                    'what a rig measures (noise, bias, sample rate, telemetry delay of '
                    'config/assimilation.yaml), the commands, and the true downhole state on '
                    'topics of its own, to an MCAP file.')
    add_config_arguments(parser)
    add_assimilation_argument(parser)
    parser.add_argument('--duration', type=float, default=90.0, metavar='S',
                        help='simulated time (s, default 90)')
    parser.add_argument('--out', required=True, metavar='RIG.mcap', help='the log to write')
    parser.add_argument('--germ-dispersion', type=float, default=0.0, metavar='DELTA',
                        help='draw the truth\'s bit-rock germ at this dispersion (default 0: '
                             'the mean law of the configuration)')
    parser.add_argument('--germ-seed', type=int, default=0, metavar='SEED',
                        help='seed of that germ (realization 0 of the stream SEED)')
    parser.set_defaults(run=run)


def add_assimilation_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--assimilation', metavar='FILE',
                        help='YAML file with an assimilation: section overriding '
                             'config/assimilation.yaml (also --set assimilation.KEY=VALUE)')


def split_settings(args):
    """(model config, assimilation settings) of --config/--assimilation/--set."""
    from drill_twin.assimilation.settings import load_assimilation, model_overrides
    from drill_twin.config import load_config

    settings = load_assimilation(args.assimilation, args.overrides)
    args.overrides = model_overrides(args.overrides)
    return load_config(args.config, args.overrides), settings


def run(args: argparse.Namespace) -> int:
    positive_seconds('--duration', args.duration)
    if Path(args.out).suffix != '.mcap':
        raise UsageError(f'--out: {args.out}: use a .mcap file name')
    from drill_twin.uncertainty.germ import germs_for_realizations, MAX_DISPERSION
    if not 0.0 <= args.germ_dispersion < MAX_DISPERSION:
        raise UsageError(f'--germ-dispersion: must be in [0, {MAX_DISPERSION:.4f}), got '
                         f'{args.germ_dispersion}')
    if args.germ_seed < 0:
        raise UsageError(f'--germ-seed: must be >= 0, got {args.germ_seed}')
    config, settings = split_settings(args)
    from drill_twin.assimilation.rig_emulator import run_rig
    from drill_twin.cli.common import preflight_or_refuse
    from drill_twin.config.loader import config_to_dict
    from drill_twin.integrator.stepping import TwinStalled

    checked = preflight_or_refuse(config, args.overrides)
    germ = None
    if args.germ_dispersion > 0:
        germ = germs_for_realizations(args.germ_dispersion, args.germ_seed, [0])[0]
    try:
        log = run_rig(config, settings, args.duration, germ=germ, system=checked.system,
                      progress=ProgressBar('rig'))
    except TwinStalled as error:
        raise blamed(config, args.overrides, f'the truth cannot be integrated: {error}') from None
    metadata = {'duration_s': repr(log.duration_s),
                'germ': json.dumps(None if germ is None else germ.tolist()),
                'config': json.dumps(config_to_dict(config)),
                'sensors': json.dumps({name: {'topic': getattr(settings.sensors, name).topic}
                                       for name in log.sensors}),
                'channel_topics': json.dumps(settings.scalar_topics())}
    write_rig_log(args.out, log, settings, metadata)
    truth = log.truth
    print(f'rig: {log.duration_s:g} s written to {args.out}: '
          + ', '.join(f'{name} {s.stamp_s.size} samples' for name, s in log.sensors.items())
          + f'; truth bit speed mean {truth.bit_speed_rad_per_s.mean():.3f} rad/s, '
          f'min {truth.bit_speed_rad_per_s.min():.3f}, max {truth.bit_speed_rad_per_s.max():.3f}')
    return 0


def _ns(seconds: float) -> int:
    return int(round(seconds * 1e9))


def write_rig_log(path, log, settings, metadata: dict[str, str]) -> None:
    """Write a RigLog (see the module docstring for the layout)."""
    from drill_twin.assimilation.measurements import joint_state_fields
    from drill_twin.recording.mcap_log import McapLog
    from drill_twin.recording.message_types import import_message_class

    joint_state = import_message_class('sensor_msgs/msg/JointState')
    float64 = import_message_class('std_msgs/msg/Float64')

    def state(t_ns, names, position, velocity, effort):
        message = joint_state()
        message.header.stamp.sec = t_ns // 1_000_000_000
        message.header.stamp.nanosec = t_ns % 1_000_000_000
        message.name = list(names)
        message.position = [float(v) for v in position]
        message.velocity = [float(v) for v in velocity]
        message.effort = [float(v) for v in effort]
        return message

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
                messages.append((_ns(arrival), topic, state(_ns(stamp), *fields)))
                joint_states.add(name)
    for topic, commands in ((itf.CMD_TOP_DRIVE_SPEED, log.speed_commands),
                            (itf.CMD_HOOK_LOAD, log.hook_commands)):
        for time_s, value in commands:
            messages.append((_ns(time_s), topic, float64(data=float(value))))
    truth = log.truth
    if truth is not None:
        for k, time_s in enumerate(truth.time_s):
            t = _ns(time_s)
            messages.append((t, TRUTH_BIT, state(
                t, [itf.BIT_AXIAL, itf.BIT_ROTATION],
                [truth.bit_depth_m[k], truth.bit_angle_rad[k]],
                [truth.rop_m_per_s[k], truth.bit_speed_rad_per_s[k]],
                [truth.weight_on_bit_n[k], truth.torque_on_bit_nm[k]])))
            messages.append((t, TRUTH_HOLE, float64(data=float(truth.hole_depth_m[k]))))
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


def read_rig_log(path, settings):
    """
    Return the RigLog of a log with the sensor topics of ``settings`` (no rclpy: CDR decoded here).

    Raises UsageError naming the problem (one line).
    """
    from drill_twin.assimilation.measurements import values_from_joint_state
    from drill_twin.assimilation.rig_log import RigLog, SensorSamples, Truth
    from drill_twin.recording import cdr
    from drill_twin.recording.reader import iter_raw, read_metadata

    sensor_of_topic = {getattr(settings.sensors, name).topic: name
                       for name in ('top_drive', 'hook', 'downhole')}
    channel_of_topic = {topic: channel for channel, topic in settings.scalar_topics().items()}
    rows = {name: [] for name in sensor_of_topic.values()}
    scalar_rows = {channel: [] for channel in channel_of_topic.values()}
    speed, hook, truth_rows, hole = [], [], [], {}
    last_ns = 0
    try:
        for schema, channel, record in iter_raw(path):
            topic = channel.topic
            last_ns = max(last_ns, record.log_time)
            try:
                if topic in sensor_of_topic:
                    stamp, position, velocity, effort = cdr.joint_state(record.data)
                    rows[sensor_of_topic[topic]].append(
                        (stamp, record.log_time, position, velocity, effort))
                elif topic in channel_of_topic:
                    scalar_rows[channel_of_topic[topic]].append(
                        (record.log_time, cdr.float64(record.data)))
                elif topic == itf.CMD_TOP_DRIVE_SPEED:
                    speed.append((record.log_time * 1e-9, cdr.float64(record.data)))
                elif topic == itf.CMD_HOOK_LOAD:
                    hook.append((record.log_time * 1e-9, cdr.float64(record.data)))
                elif topic == TRUTH_BIT:
                    stamp, position, velocity, effort = cdr.joint_state(record.data)
                    truth_rows.append((stamp * 1e-9, velocity[1], position[1], velocity[0],
                                       effort[1], effort[0], position[0]))
                elif topic == TRUTH_HOLE:
                    hole[record.log_time] = cdr.float64(record.data)
            except (ValueError, IndexError) as error:
                raise UsageError(f'{path}: a message on {topic} is malformed ({error})') from None
    except FileNotFoundError as error:
        raise UsageError(str(error)) from None
    metadata = read_metadata(path)
    duration = float(metadata.get(METADATA, {}).get('duration_s', last_ns * 1e-9))
    sensors = {}
    for name, items in rows.items():
        if not items:
            continue
        items.sort(key=lambda item: item[0])
        stamp = np.array([i[0] for i in items]) * 1e-9
        arrival = np.array([i[1] for i in items]) * 1e-9
        try:
            read = [values_from_joint_state(name, None, *i[2:]) for i in items]
            values = {c: [r[c] for r in read] for c in read[0] if c not in scalar_rows}
        except (ValueError, KeyError):
            raise UsageError(f'{path}: {name} messages lack their fields (see drill-twin rig '
                             '--help for the layout)') from None
        sensors[name] = SensorSamples(stamp, arrival,
                                      {k: np.asarray(v, dtype=float) for k, v in values.items()})
    scalars = {}
    for channel, items in scalar_rows.items():     # unstamped: received less the delay
        if items:
            arrival = np.array([i[0] for i in sorted(items)]) * 1e-9
            scalars[channel] = SensorSamples(
                arrival - settings.sensor_of(channel).delay_s, arrival,
                {channel: np.array([i[1] for i in sorted(items)], dtype=float)})
    if not sensors and not scalars:
        raise UsageError(f'{path}: no measurement topics ('
                         + ', '.join([*sensor_of_topic, *channel_of_topic]) + ')')
    if not speed or not hook:
        raise UsageError(f'{path}: no commands on {itf.CMD_TOP_DRIVE_SPEED} and '
                         f'{itf.CMD_HOOK_LOAD}')
    truth = None
    if truth_rows:
        columns = np.array(truth_rows, dtype=float).T
        holes = np.array([hole.get(_ns(t), math.nan) for t in columns[0]])
        truth = Truth(columns[0], columns[1], columns[2], columns[3], columns[4], columns[5],
                      columns[6], holes)
    return RigLog(duration_s=duration, sensors=sensors, speed_commands=np.array(speed),
                  hook_commands=np.array(hook), truth=truth,
                  metadata=metadata.get(METADATA, {}), scalars=scalars)
