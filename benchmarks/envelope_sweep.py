"""A scripted sweep of the driller's whole envelope through the running twin.

    python benchmarks/envelope_sweep.py [--minutes 30] [--members 64] [--delta 0.1]
                                        [--time-step 0.005] [--seed 0] [--log-dir DIR]

Starts ``drill-twin twin --fast`` (a separate process, as a rig would see it) with the given
ensemble and drives it by topic, on the twin's own clock (/clock), through a command script
that covers the envelope of issue 10: top-drive speed 0 ... 30 rad/s (stopped on bottom and
restarted), hook load from above the string's weight (bit lifted off bottom) down to a weight
on bit of 300 kN, with step changes of either at arbitrary instants (a seeded
``numpy.random.Generator`` picks them). It listens to ``/diagnostics`` and prints, at the end,
the twin's own counters from its last health report (resets of members and of the mean model,
retried steps, failed steps, rejected commands), the number of ERROR/WARN health reports, the
simulated and wall time. Not part of the test suite.
"""
from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

SPEEDS_RAD_PER_S = (0.0, 2.0, 5.215, 10.0, 15.0, 20.0, 30.0)
WOB_N = (-1e3, 0.0, 50e3, 100e3, 150e3, 200e3, 250e3, 300e3)
"""Static weights on bit of the script (N, compression > 0); < 0: the hook pulls more than the
string weighs, so the bit is lifted off bottom (the twin accepts at most the weight plus the
drag at a block's speed, 1.19 kN for the paper's string: the string then rises at most at
1 m/s)."""


def string_weight_n(config) -> float:
    """The hook load that holds the whole string with no weight on the bit (N): the prestress's
    hook load plus the WOB it was computed for (the model's own count)."""
    from drill_twin.fem.model import build_model
    model = build_model(config)
    return model.prestress.hook_load_n + abs(config.bit_rock.static_weight_on_bit_n)


def command_script(duration_s: float, rng: np.random.Generator):
    """(time s, top-drive speed rad/s, WOB N) changes: every speed at every WOB, then
    random steps of either at random instants until ``duration_s``."""
    script, t = [], 5.0
    for wob in WOB_N:
        for speed in SPEEDS_RAD_PER_S:
            if t >= duration_s:
                return script
            script.append((t, speed, wob))
            t += float(rng.uniform(8.0, 25.0))
    while t < duration_s:
        script.append((t, float(rng.choice(SPEEDS_RAD_PER_S)), float(rng.choice(WOB_N))))
        t += float(rng.exponential(15.0))
    return script


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--minutes', type=float, default=30.0, help='simulated minutes')
    parser.add_argument('--members', type=int, default=64)
    parser.add_argument('--delta', type=float, default=0.1)
    parser.add_argument('--time-step', type=float, default=0.0,
                        help='model step of the twin (s); 0: the twin\'s default')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--log-dir', default=None, help='keep the twin\'s log here')
    args = parser.parse_args(argv)

    folder = Path(tempfile.mkdtemp(prefix='envelope_sweep_'))
    env = dict(os.environ, ROS_DOMAIN_ID=str(random.SystemRandom().randint(1, 101)),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', RMW_IMPLEMENTATION='rmw_fastrtps_cpp',
               ROS_LOG_DIR=str(folder / 'ros_log'), RERUN_TELEMETRY='0')
    os.environ.update({k: env[k] for k in ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE',
                                           'RMW_IMPLEMENTATION', 'ROS_LOG_DIR')})
    from drill_twin.config import load_config
    config = load_config()
    weight = string_weight_n(config)
    duration = 60.0 * args.minutes
    script = command_script(duration, np.random.default_rng(args.seed))

    command = [sys.executable, '-m', 'drill_twin.cli.main', 'twin', '--fast',
               '--ensemble', str(args.members), '--delta', repr(args.delta),
               '--seed', str(args.seed), '--duration', repr(duration)]
    command += ['--log-dir', args.log_dir] if args.log_dir else ['--no-log']
    if args.time_step > 0:
        command += ['--ros-args', '-p', f'time_step_s:={args.time_step!r}']
    print(f'string weight as the model counts it: {weight / 1e3:.1f} kN; '
          f'{len(script)} command changes over {args.minutes:g} simulated minutes')
    print(' '.join(command), flush=True)

    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import ExternalShutdownException
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import Float64

    from drill_twin import interface as itf

    rclpy.init()
    node = rclpy.create_node('envelope_sweep')
    reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    speed_pub = node.create_publisher(Float64, itf.CMD_TOP_DRIVE_SPEED, reliable)
    hook_pub = node.create_publisher(Float64, itf.CMD_HOOK_LOAD, reliable)
    state = {'twin_s': 0.0, 'health': {}, 'levels': {0: 0, 1: 0, 2: 0}, 'messages': set()}

    def on_clock(message):
        state['twin_s'] = message.clock.sec + 1e-9 * message.clock.nanosec

    def on_diagnostics(message):
        for status in message.status:
            level = int.from_bytes(status.level, 'little') if isinstance(status.level, bytes) \
                else int(status.level)
            if 'health' in status.name or status.name.endswith('twin'):
                state['health'] = {kv.key: kv.value for kv in status.values}
                state['levels'][min(level, 2)] = state['levels'].get(min(level, 2), 0) + 1
            if level >= 1:
                state['messages'].add(status.message[:160])

    node.create_subscription(Clock, itf.CLOCK, on_clock,
                             QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
    node.create_subscription(DiagnosticArray, itf.DIAGNOSTICS, on_diagnostics, 100)

    start = time.monotonic()
    twin = subprocess.Popen(command, env=env, cwd=ROOT)
    next_command = 0
    try:
        while twin.poll() is None:
            rclpy.spin_once(node, timeout_sec=0.05)
            while next_command < len(script) and state['twin_s'] >= script[next_command][0]:
                _, speed, wob = script[next_command]
                speed_pub.publish(Float64(data=speed))
                hook_pub.publish(Float64(data=weight - wob))
                next_command += 1
    except (KeyboardInterrupt, ExternalShutdownException):
        twin.send_signal(signal.SIGINT)
    finally:
        status = twin.wait()
        wall = time.monotonic() - start
        node.destroy_node()
        rclpy.try_shutdown()

    print(f'\ntwin exit status {status}; {state["twin_s"]:.1f} s simulated in {wall:.0f} s wall '
          f'(RTF {state["twin_s"] / max(wall, 1e-9):.2f}); {next_command} command changes sent')
    print('health reports OK / WARN / ERROR: '
          f'{state["levels"][0]} / {state["levels"][1]} / {state["levels"][2]}')
    print('last health values:')
    for key, value in sorted(state['health'].items()):
        print(f'  {key}: {value}')
    if state['messages']:
        print('distinct WARN/ERROR messages:')
        for text in sorted(state['messages'])[:40]:
            print('  ' + text)
    return status


if __name__ == '__main__':
    sys.exit(main())
