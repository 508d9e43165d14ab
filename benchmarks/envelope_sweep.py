"""A scripted sweep of the driller's whole envelope through the running twin.

    python benchmarks/envelope_sweep.py [--minutes 30] [--members 64] [--delta 0.1]
                                        [--time-step 0.005] [--seed 0] [--log-dir DIR]

Starts ``drill-twin twin --fast`` (a separate process, as a rig would see it) with the given
ensemble and drives it by topic, on the twin's own clock (/clock), as a driller would
(:class:`Driller`, every draw from a seeded ``numpy.random.Generator``): top-drive speed
0 ... 30 rad/s (stopped on bottom and restarted), WOB 0 ... 300 kN through the hook load or the
autodriller's set-point, step changes at random instants, and pick-ups with the drawworks,
rotation off bottom, a run back down and a gentle tag. It waits for the axial mode's echo
before the set-points that depend on it, prints every command, listens to ``/diagnostics``
and prints, at the end, the resets by reason and the twin's own counters from its last health
report (resets of members and of the mean model, retried steps, failed steps, rejected
commands), the number of ERROR/WARN health reports, the simulated and wall time.
``--offline`` drives the twin's engine in this process instead. Not part of the test suite.
"""
from __future__ import annotations

import argparse
import os
import random
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

SPEEDS_RAD_PER_S = (0.0, 2.0, 5.215, 10.0, 15.0, 20.0, 30.0)
WOB_N = (0.0, 50e3, 100e3, 150e3, 200e3, 250e3, 300e3)
"""Static weights on bit of the script (N, compression > 0). 0: the hook holds the whole string's
weight (the bit rests on bottom with no weight, or hovers where it is)."""
PICK_UP_SPEEDS_M_PER_S = (0.1, 0.25, 0.5, 1.0)
"""Block speeds of a pick-up (up to the fastest block speed the twin accepts, 1 m/s)."""
LOWERING_SPEEDS_M_PER_S = (0.1, 0.25, 0.5)
"""Block speeds of running back down to TAG_DISTANCE_M above bottom."""
TAG_SPEED_M_PER_S = 0.01
"""Block speed of the last TAG_DISTANCE_M: a driller tags bottom gently (36 m/h, about the ROP).
The bit-rock law cutting at block speed would be violent: at 0.1 m/s and 2 rad/s its mean law
asks 3.6 MN and 240 kN m (``BitRockLaw.mean(0.1, 2.0)`` of the default configuration)."""
TAG_DISTANCE_M = 0.5


def string_weight_n(config) -> float:
    """The hook load that holds the whole string with no weight on the bit (N): the prestress's
    hook load plus the WOB it was computed for (the model's own count)."""
    from drill_twin.fem.model import build_model
    model = build_model(config)
    return model.prestress.hook_load_n + abs(config.bit_rock.static_weight_on_bit_n)


class Driller:
    """
    A driller's hands on the twin, reacting to the bit's and the hole's depth.

    On bottom the axial input is the hook load (``WOB_N`` through the string's weight) or the
    autodriller's WOB set-point; speed and WOB change in steps at random instants (mean 15 s),
    including a stopped top drive. Now and then the driller picks up 0.5-3 m off bottom with the
    drawworks (block velocity up to 1 m/s), rotates off bottom at random speeds, runs back down
    and tags bottom at ``TAG_SPEED_M_PER_S``, then drills on in either axial mode. Every draw
    comes from ``rng``. :meth:`commands` returns the (command, value) pairs to send now;
    commands are the twin's short names (drill_twin.interface.COMMANDS).
    """

    def __init__(self, weight_n: float, rng: np.random.Generator, start_s: float = 5.0,
                 pick_up_probability: float = 0.12):
        self.weight_n = weight_n
        self.pick_up_probability = pick_up_probability
        self.rng = rng
        self.phase = 'drill'
        self.axial = 'hook_load'
        self.next_s = start_s
        self.wob_n = 100e3
        self.target_m = 0.0                     # the pick-up's height off bottom
        self.hover_until_s = 0.0
        self.pick_ups = 0

    def _wob_command(self, wob):
        self.wob_n = wob
        if self.axial == 'hook_load':
            return [('hook_load', self.weight_n - wob)]
        return [('wob_setpoint', wob)]

    def commands(self, t: float, bit_depth_m: float, hole_depth_m: float):
        off = hole_depth_m - bit_depth_m
        rng = self.rng
        if self.phase == 'drill':
            if t < self.next_s:
                return []
            self.next_s = t + float(rng.exponential(15.0))
            draw = rng.uniform()
            if draw < self.pick_up_probability and off < 1e-3:
                self.phase, self.pick_ups = 'pick_up', self.pick_ups + 1
                self.target_m = float(rng.uniform(0.5, 3.0))
                return [('axial_mode', 'block_velocity'),
                        ('block_velocity', -float(rng.choice(PICK_UP_SPEEDS_M_PER_S)))]
            if draw < 0.2:
                self.axial = 'autodriller' if self.axial == 'hook_load' else 'hook_load'
                return [('axial_mode', self.axial)] + self._wob_command(self.wob_n)
            if draw < 0.6:
                return [('top_drive_speed', float(rng.choice(SPEEDS_RAD_PER_S)))]
            return self._wob_command(float(rng.choice(WOB_N)))
        if self.phase == 'pick_up' and off >= self.target_m:
            self.phase, self.hover_until_s = 'hover', t + float(rng.uniform(5.0, 20.0))
            self.next_s = t + float(rng.uniform(1.0, 5.0))
            return [('block_velocity', 0.0)]
        if self.phase == 'hover':
            if t >= self.hover_until_s:
                self.phase = 'lower'
                return [('block_velocity', float(rng.choice(LOWERING_SPEEDS_M_PER_S)))]
            if t >= self.next_s:
                self.next_s = t + float(rng.uniform(2.0, 8.0))
                return [('top_drive_speed', float(rng.choice(SPEEDS_RAD_PER_S)))]
        if self.phase == 'lower' and off < TAG_DISTANCE_M:
            self.phase = 'tag'
            return [('block_velocity', TAG_SPEED_M_PER_S)]
        if self.phase == 'tag' and off < 1e-4:
            self.phase, self.next_s = 'drill', t + float(rng.exponential(15.0))
            self.axial = 'hook_load' if rng.uniform() < 0.5 else 'autodriller'
            wob = float(rng.choice(WOB_N))
            if self.axial == 'hook_load':
                return [('axial_mode', 'hook_load'), ('hook_load', self.weight_n - wob)]
            self.wob_n = wob
            return [('wob_setpoint', wob), ('axial_mode', 'autodriller')]
        return []


def run_offline(args, config, weight, duration):
    """The same driller on the twin's engine in this process (no ROS): quick to iterate."""
    from collections import Counter
    from drill_twin.twin.engine import TwinEngine
    from drill_twin.twin.ensemble import EnsembleSettings
    if args.time_step > 0:
        from drill_twin.config import load_config
        config = load_config(None, [f'integration.time_step_s={args.time_step!r}'])
    engine = TwinEngine(config, EnsembleSettings(members=args.members, dispersion=args.delta,
                                                 seed=args.seed, separate_process=False))
    driller = Driller(weight, np.random.default_rng(args.seed), pick_up_probability=args.pick_ups)
    setters = {'top_drive_speed': engine.set_top_drive_speed, 'hook_load': engine.set_hook_load,
               'axial_mode': engine.set_axial_mode, 'block_velocity': engine.set_block_velocity,
               'wob_setpoint': engine.set_weight_on_bit_setpoint}
    kinds, reasons, sent = Counter(), Counter(), 0
    start = time.monotonic()
    steps = max(int(round(0.01 / engine.dt)), 1)
    while engine.time_s < duration:
        o = engine.simulator.observe(detailed=1)
        for name, value in driller.commands(engine.time_s, float(o.bit_depth_m[0]),
                                            float(o.hole_depth_m[0])):
            if args.verbose:
                print(f'{engine.time_s:8.2f} s command {name} {value} (bit {o.bit_depth_m[0]:.3f}'
                      f' m, hole {o.hole_depth_m[0]:.3f} m)', flush=True)
            setters[name](value)
            sent += 1
        snapshot = engine.advance(steps)
        for event in snapshot.events:
            kinds[event.kind] += 1
            if event.kind in ('diverged', 'implausible'):
                reasons[_reason_kind(event.values.get('reason', event.message))] += 1
                if args.verbose:
                    print(f'{event.time_s:8.2f} s {event.message}', flush=True)
    wall = time.monotonic() - start
    health = engine.snapshot().health
    engine.close()
    print(f'{engine.time_s:.1f} s simulated in {wall:.0f} s wall; {sent} commands; '
          f'{driller.pick_ups} pick-ups')
    print('events:', dict(kinds))
    print('reset reasons:', dict(reasons))
    for key in ('resets', 'mean_model_resets', 'ensemble_resets', 'retries',
                'mean_model_failed_steps', 'rejected_commands'):
        print(f'  {key}: {health.get(key)}')
    return 0


def _reason_kind(reason: str) -> str:
    """The quantity a reset's reason names ('WOB', 'TOB', 'the top's axial speed', ...)."""
    head = reason.split(' is ')[0].split(' (')[0]
    return ' '.join(re.sub(r'[-+]?\d[\d.e+-]*', ' ', head).split())


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--minutes', type=float, default=30.0, help='simulated minutes')
    parser.add_argument('--members', type=int, default=64)
    parser.add_argument('--delta', type=float, default=0.1)
    parser.add_argument('--time-step', type=float, default=0.0,
                        help='model step of the twin (s); 0: the twin\'s default')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--log-dir', default=None, help='keep the twin\'s log here')
    parser.add_argument('--offline', action='store_true',
                        help='drive the twin\'s engine in this process (no ROS, no log)')
    parser.add_argument('--verbose', action='store_true', help='print every reset (offline)')
    parser.add_argument('--pick-ups', type=float, default=0.12,
                        help='probability that a change on bottom is a pick-up (0: none)')
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
    print(f'string weight as the model counts it: {weight / 1e3:.1f} kN; '
          f'{args.minutes:g} simulated minutes', flush=True)
    if args.offline:
        return run_offline(args, config, weight, duration)

    command = [sys.executable, '-m', 'drill_twin.cli.main', 'twin', '--fast',
               '--ensemble', str(args.members), '--delta', repr(args.delta),
               '--seed', str(args.seed), '--duration', repr(duration)]
    command += ['--log-dir', args.log_dir] if args.log_dir else ['--no-log']
    if args.time_step > 0:
        command += ['--ros-args', '-p', f'time_step_s:={args.time_step!r}']
    print(' '.join(command), flush=True)

    from collections import Counter

    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import ExternalShutdownException
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import Float64, String

    from drill_twin import interface as itf

    rclpy.init()
    node = rclpy.create_node('envelope_sweep')
    reliable = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    publishers = {name: (node.create_publisher(String if topic in itf.MODE_COMMANDS else Float64,
                                               topic, reliable),
                         String if topic in itf.MODE_COMMANDS else Float64)
                  for topic, name in itf.COMMANDS.items()}
    state = {'twin_s': 0.0, 'health': {}, 'levels': {0: 0, 1: 0, 2: 0}, 'messages': set(),
             'bit': 0.0, 'hole': 0.0, 'reasons': Counter(), 'kinds': Counter()}

    def on_clock(message):
        state['twin_s'] = message.clock.sec + 1e-9 * message.clock.nanosec

    def on_diagnostics(message):
        for status in message.status:
            level = int.from_bytes(status.level, 'little') if isinstance(status.level, bytes) \
                else int(status.level)
            values = {kv.key: kv.value for kv in status.values}
            if 'health' in status.name or status.name.endswith('twin'):
                state['health'] = values
                state['levels'][min(level, 2)] = state['levels'].get(min(level, 2), 0) + 1
            elif 'reason' in values:
                state['reasons'][_reason_kind(values['reason'])] += 1
            if level >= 1:
                state['messages'].add(status.message[:160])

    def keep(key):
        def on_value(message):
            state[key] = message.data
        return on_value

    node.create_subscription(Clock, itf.CLOCK, on_clock,
                             QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
    node.create_subscription(DiagnosticArray, itf.DIAGNOSTICS, on_diagnostics, 1000)
    def on_mode_applied(message):
        state['mode_applied'] = message.name[0].split('=', 1)[1] if message.name else None

    from sensor_msgs.msg import JointState
    node.create_subscription(JointState, itf.cmd_applied_topic(itf.CMD_AXIAL_MODE),
                             on_mode_applied, 10)
    node.create_subscription(Float64, itf.SURFACE_BIT_DEPTH, keep('bit'), 10)
    node.create_subscription(Float64, itf.SURFACE_HOLE_DEPTH, keep('hole'), 10)

    driller = Driller(weight, np.random.default_rng(args.seed), pick_up_probability=args.pick_ups)
    start = time.monotonic()
    twin = subprocess.Popen(command, env=env, cwd=ROOT)
    sent, queue = 0, []
    state['mode_applied'] = 'hook_load'
    try:
        while twin.poll() is None:
            rclpy.spin_once(node, timeout_sec=0.02)
            if state['hole'] <= 0.0:                    # no reading yet
                continue
            queue += driller.commands(state['twin_s'], state['bit'], state['hole'])
            # A set-point that depends on the axial mode waits for the mode's echo: commands on
            # different topics may arrive in any order.
            while queue and (queue[0][0] == 'axial_mode'
                             or state['mode_applied'] == state.get('mode_sent', 'hook_load')):
                name, value = queue.pop(0)
                publisher, kind = publishers[name]
                publisher.publish(kind(data=value))
                sent += 1
                print(f'  [{state["twin_s"]:8.2f} s] command {name} {value} (bit '
                      f'{state["hole"] - state["bit"]:.3f} m off bottom)', flush=True)
                if name == 'axial_mode':
                    state['mode_sent'] = value
                    break
    except (KeyboardInterrupt, ExternalShutdownException):
        twin.send_signal(signal.SIGINT)
    finally:
        status = twin.wait()
        wall = time.monotonic() - start
        node.destroy_node()
        rclpy.try_shutdown()
    next_command = f'{sent} commands ({driller.pick_ups} pick-ups);'
    print(f'\ntwin exit status {status}; {state["twin_s"]:.1f} s simulated in {wall:.0f} s wall '
          f'(RTF {state["twin_s"] / max(wall, 1e-9):.2f}); {next_command}')
    print('reset reasons:', dict(state['reasons']))
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
