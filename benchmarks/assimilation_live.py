"""The twin node following a rig over ROS topics: a rig log played into a running twin.

    python benchmarks/assimilation_live.py RIG.mcap [--members 64] [--duration S]
        [--settle 0 10 20] [--out DIR] [--log-dir DIR] [--assimilation FILE]

RIG.mcap is a rig emulator's log (``drill-twin rig``; ``benchmarks/assimilation.py`` writes the
twin-on-twin scenario of docs/ASSIMILATION.md as DIR/rig.mcap). A player node publishes, over
FastDDS on this machine, ``/clock`` in 10 ms increments, the log's commands at their times and
its sensor messages (``sensor_msgs/JointState``, stamped when sampled) at their arrival times,
to the twin node (``use_sim_time``, 5 ms steps, the ensemble in its worker process) built as
``ros2 run drill_twin twin`` builds it (``--log-dir``: the assimilating twin logs there), once
with ``assimilation_enabled`` and once without (the open-loop reference, same members and
germs). The player waits for the twin to reach each /clock before the next, so the result does
not depend on this machine's speed. The bit speed of the twin's ensemble topics (mean and 95 %
bounds, 20 Hz) is scored against the log's truth: RMS error, the open loop's, coverage of the
truth by the bounds, after each settling time; and the wall time (real-time factor of the
loop). ``--assimilation FILE``: the twin's assimilation_config (default the shipped one); the
estimated sensor biases heard (if it estimates any) are printed and kept. Writes DIR/live.json.
"""
from __future__ import annotations

from drill_twin.cli import blas_threads

blas_threads.limit_to_one()       # before numpy: two runs side by side must not spin

import argparse
import json
import math
import os
import random
import tempfile
import time
from pathlib import Path

import numpy as np

CLOCK_STEP_S = 0.05
"""The played clock's increment (s): the twin catches up within a tick or two."""
EPOCH_NS = 100_000_000_000
"""The played clock's start (a stamp 0 means 'unset' to the twin)."""


def play(log, members: int, duration_s: float, assimilation: bool, settings,
         log_dir: str | None = None, assimilation_config: str = '') -> dict:
    """Play the log into a fresh twin; return its ensemble's bit speed (stamps s, mean, lower, upper)."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    from drill_twin import interface as itf
    from drill_twin.assimilation.measurements import joint_state_fields
    from drill_twin.recording.qos import rclpy_qos_profile
    from drill_twin.ros.parameters import TwinParameters
    from drill_twin.ros.twin_node import create_twin_node

    params = TwinParameters.from_values({
        'ensemble_members': members, 'ensemble_dispersion': settings.filter.prior_dispersion,
        'seed': settings.filter.seed, 'assimilation_enabled': assimilation,
        'ensemble_rate_hz': 20.0, 'log_enabled': log_dir is not None,
        'log_dir': log_dir or 'runs', 'health_rate_hz': 1.0,
        'assimilation_config': assimilation_config})
    node = create_twin_node(params, parameter_overrides=[Parameter('use_sim_time', value=True)])
    player = rclpy.create_node('rig_player')
    heard = {topic: [] for topic in (itf.ENSEMBLE_MEAN, itf.ENSEMBLE_LOWER, itf.ENSEMBLE_UPPER)}
    deep = QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE)
    for topic in heard:
        player.create_subscription(JointState, topic, heard[topic].append, deep)
    from std_msgs.msg import Float64MultiArray
    biases = {topic: [] for topic in (itf.ASSIMILATION_BIAS_MEAN, itf.ASSIMILATION_BIAS_LOWER,
                                      itf.ASSIMILATION_BIAS_UPPER)}
    for topic in biases:
        player.create_subscription(Float64MultiArray, topic, biases[topic].append, deep)
    clock = player.create_publisher(Clock, itf.CLOCK, rclpy_qos_profile(itf.CLOCK_QOS))
    commands = {itf.CMD_TOP_DRIVE_SPEED: log.speed_commands, itf.CMD_HOOK_LOAD: log.hook_commands}
    command_out = {topic: player.create_publisher(Float64, topic,
                                                  rclpy_qos_profile(itf.COMMAND_QOS))
                   for topic in commands}
    sensor_out = {name: player.create_publisher(
        JointState, getattr(settings.sensors, name).topic, rclpy_qos_profile(itf.STATE_QOS))
        for name in log.sensors}
    queue = [(float(t), 0, topic, Float64(data=float(v)))
             for topic, rows in commands.items() for t, v in rows]
    for name, samples in log.sensors.items():
        for k, (stamp, arrival) in enumerate(zip(samples.stamp_s, samples.arrival_s)):
            message = JointState()
            names, position, velocity, effort = joint_state_fields(
                name, {c: v[k] for c, v in samples.values.items()})
            message.name, message.position = names, position
            message.velocity, message.effort = velocity, effort
            message.header.stamp.sec, message.header.stamp.nanosec = divmod(
                EPOCH_NS + int(round(stamp * 1e9)), 1_000_000_000)
            queue.append((float(arrival), 1, name, message))
    for channel, samples in log.scalars.items():     # channels on Float64 topics of their own
        sensor_out[channel] = player.create_publisher(
            Float64, settings.channel(channel).topic, rclpy_qos_profile(itf.STATE_QOS))
        for arrival, value in zip(samples.arrival_s, samples.values[channel]):
            queue.append((float(arrival), 1, channel, Float64(data=float(value))))
    queue.sort(key=lambda item: (item[0], item[1]))
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    executor.add_node(player)
    used = [*node.measurement_topics, *node.scalar_measurement_topics]   # (none in open loop)
    ends = ([lambda t=t: node.count_subscribers(t) > 0 for t in heard]
            + [lambda p=p: p.get_subscription_count() > 0
               for p in [clock, *command_out.values()]]
            + [lambda p=p: p.get_subscription_count() > 0
               for p in sensor_out.values() if p.topic_name in used])
    while not all(end() for end in ends):
        executor.spin_once(timeout_sec=0.05)
    while not node.clock.started:             # /clock is best effort: the first may be lost
        clock.publish(Clock(clock=_stamp(EPOCH_NS)))
        executor.spin_once(timeout_sec=0.05)
    assert node.clock.epoch_ns == EPOCH_NS
    start = time.perf_counter()
    t, index = 0.0, 0
    try:
        while t <= duration_s + 1e-9:
            while index < len(queue) and queue[index][0] <= t + 1e-9:
                _, kind, target, message = queue[index]
                (command_out[target] if kind == 0 else sensor_out[target]).publish(message)
                index += 1
            for _ in range(3):                      # deliver them before the clock moves on
                executor.spin_once(timeout_sec=0.0)
            clock.publish(Clock(clock=_stamp(EPOCH_NS + int(round(t * 1e9)))))
            deadline = time.monotonic() + 30.0
            while node.engine.time_s < t - 1e-9:
                if time.monotonic() > deadline:
                    raise RuntimeError(f'the twin did not reach /clock {t:.3f} s in 30 s')
                executor.spin_once(timeout_sec=0.01)
            t += CLOCK_STEP_S
        for _ in range(50):
            executor.spin_once(timeout_sec=0.01)
        wall = time.perf_counter() - start
        health = dict(node.engine.snapshot().health)
    finally:
        node.close()
        executor.shutdown()
        player.destroy_node()
        node.destroy_node()

    def series(topic):
        messages = heard[topic]
        stamps = np.array([(m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
                            - EPOCH_NS) * 1e-9 for m in messages])
        return stamps, np.array([m.velocity[1] for m in messages])

    stamps, mean = series(itf.ENSEMBLE_MEAN)
    _, lower = series(itf.ENSEMBLE_LOWER)
    _, upper = series(itf.ENSEMBLE_UPPER)
    n = min(len(mean), len(lower), len(upper))
    bias = {}
    if biases[itf.ASSIMILATION_BIAS_MEAN]:
        last = {topic: heard_[-1] for topic, heard_ in biases.items() if heard_}
        labels = last[itf.ASSIMILATION_BIAS_MEAN].layout.dim[0].label.split(',')
        bias = {channel: {name: float(last[topic].data[j]) for name, topic in (
            ('mean', itf.ASSIMILATION_BIAS_MEAN), ('lower', itf.ASSIMILATION_BIAS_LOWER),
            ('upper', itf.ASSIMILATION_BIAS_UPPER)) if topic in last}
            for j, channel in enumerate(labels)}
    return {'time_s': stamps[:n], 'mean': mean[:n], 'lower': lower[:n], 'upper': upper[:n],
            'wall_s': wall, 'health': health, 'sensor_bias_final': bias}


def _stamp(ns: int):
    from builtin_interfaces.msg import Time
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def score(run: dict, truth, settle_s: float) -> dict:
    keep = run['time_s'] >= settle_s
    actual = np.interp(run['time_s'][keep], truth.time_s, truth.bit_speed_rad_per_s)
    inside = (run['lower'][keep] <= actual) & (actual <= run['upper'][keep])
    return {'rms_error_rad_per_s': float(np.sqrt(np.mean((run['mean'][keep] - actual) ** 2))),
            'coverage_95': float(inside.mean()), 'samples': int(keep.sum())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('rig_log')
    parser.add_argument('--members', type=int, default=64)
    parser.add_argument('--duration', type=float, default=None)
    parser.add_argument('--settle', type=float, nargs='+', default=[0.0, 10.0, 20.0])
    parser.add_argument('--out', default='assimilation-live')
    parser.add_argument('--log-dir', default=None, help='log the assimilating twin there')
    parser.add_argument('--assimilation', default='',
                        help="the twin's assimilation_config (default: the shipped one)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    folder = Path(tempfile.mkdtemp(prefix='drill_twin_live_'))
    os.environ.update({'RMW_IMPLEMENTATION': 'rmw_fastrtps_cpp',
                       'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST',
                       'ROS_DOMAIN_ID': str(random.SystemRandom().randint(1, 101)),
                       'ROS_LOG_DIR': str(folder / 'log'), 'RERUN_TELEMETRY': '0'})
    import rclpy
    from threadpoolctl import threadpool_limits

    from drill_twin.assimilation.settings import load_assimilation
    from drill_twin.cli.rig_files import read_rig_log

    settings = load_assimilation(args.assimilation or None)
    log = read_rig_log(args.rig_log, settings)
    if log.truth is None:
        raise SystemExit(f'{args.rig_log}: no truth to score against')
    duration = min(args.duration or log.duration_s, log.duration_s)
    rclpy.init()
    try:
        with threadpool_limits(limits=1, user_api='blas'):
            runs = {name: play(log, args.members, duration, on, settings,
                               args.log_dir if on else None, args.assimilation)
                    for name, on in (('assimilation', True), ('open_loop', False))}
    finally:
        rclpy.try_shutdown()
    result = {'rig_log': str(args.rig_log), 'duration_s': duration, 'members': args.members,
              'load_average': os.getloadavg()}
    print(f'{duration:g} s of rig log, {args.members} members; load average '
          f'{os.getloadavg()[0]:.2f}')
    print('settle s | RMS error rad/s | open loop | ratio | coverage 95 | open-loop coverage')
    for settle in args.settle:
        a, o = (score(runs[k], log.truth, settle) for k in ('assimilation', 'open_loop'))
        result[f'settle_{settle:g}'] = {'assimilation': a, 'open_loop': o}
        print(f'{settle:8g} | {a["rms_error_rad_per_s"]:15.3f} | {o["rms_error_rad_per_s"]:9.3f} '
              f'| {a["rms_error_rad_per_s"] / o["rms_error_rad_per_s"]:5.2f} | '
              f'{a["coverage_95"]:11.2f} | {o["coverage_95"]:.2f}')
    for name, run in runs.items():
        h = run['health']
        result[name] = {'wall_s': run['wall_s'], 'real_time_factor': duration / run['wall_s'],
                        'measurements_used': h['measurements_used'],
                        'measurements_refused': h['measurements_refused'],
                        'resets': h['resets'], 'sensor_bias_final': run['sensor_bias_final']}
        for channel, bias in run['sensor_bias_final'].items():
            print(f'{name}: estimated {channel} sensor bias {bias.get("mean", math.nan):.4g} '
                  f'({bias.get("lower", math.nan):.4g} ... {bias.get("upper", math.nan):.4g})')
        print(f'{name}: {run["wall_s"]:.0f} s of wall time (real-time factor '
              f'{duration / run["wall_s"]:.2f}), samples used {h["measurements_used"]}, '
              f'refused {h["measurements_refused"]}, resets {h["resets"]}')
    (out / 'live.json').write_text(json.dumps(result, indent=2) + '\n')


if __name__ == '__main__':
    main()
