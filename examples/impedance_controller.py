#!/usr/bin/env python3
"""
An external stick-slip controller for the twin: the impedance law through topics.

The twin's top drive runs dynamic under its plain PI speed loop (this node sends
``dynamic`` on /drill_twin/cmd/top_drive_mode and ``stiff`` on
/drill_twin/cmd/top_drive_controller when it starts). At every surface torque reading it
commands the drive's speed set-point on /drill_twin/cmd/top_drive_speed with the Z-Torque law
the twin also has built in (``top_drive.controller: impedance``, docs/DRIVES.md):

    omega_sp = omega_ref - (T - <T>) / zeta,   <T>' = (T - <T>) / tau_m,

T the surface torque (/drill_twin/surface/torque, N m, through a first-order low-pass of
``--torque-filter`` s: the loop outside has a delay of a tick or two that the built-in law,
closed within the model step, has not; unfiltered, the delayed feedback rings at the tick
rate, docs/DRIVES.md, "An external controller in the loop"), zeta the impedance (N m s/rad;
the pipe's characteristic impedance I_p sqrt(rho k_s G) of the top section by default, as the
built-in one), tau_m the mean filter's time constant (s). Readings are taken one per twin
tick (``--sample-period``, the twin's 1 / rate_hz).

It also measures its own loop: every command's value is remembered with the wall time it was
published and the twin time of the reading it answered (the stamp of the latest
/drill_twin/top/state, published in the same tick just before the surface readings); the echo
on /drill_twin/cmd_applied/top_drive_speed, stamped with the twin time the command took effect,
gives the latency in twin time, the time from the publication to the effect (the twin's
clock against this system's clock: meaningful when the twin runs in real time on the same
machine) and, on arrival, the round trip in wall time (command out to the twin, echo back).

Run beside a twin (``drill-twin twin start --ros-args -p model_overrides:=[...]``):

    python examples/impedance_controller.py --reference 5.215 --duration 60

and stop it with Ctrl-C; it prints the latencies it measured.
"""
from __future__ import annotations

import argparse
import math
import time

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, String

CMD_TOP_DRIVE_SPEED = '/drill_twin/cmd/top_drive_speed'
CMD_TOP_DRIVE_MODE = '/drill_twin/cmd/top_drive_mode'
CMD_TOP_DRIVE_CONTROLLER = '/drill_twin/cmd/top_drive_controller'
APPLIED_TOP_DRIVE_SPEED = '/drill_twin/cmd_applied/top_drive_speed'
SURFACE_TORQUE = '/drill_twin/surface/torque'
SURFACE_SPEED = '/drill_twin/surface/speed'
TOP_STATE = '/drill_twin/top/state'


def pipe_impedance_nm_s_per_rad(outer_m=0.127, inner_m=0.095, density=7850.0,
                                shear_pa=210.0e9 / 2.58, shear_factor=6.0 / 7.0) -> float:
    """
    Return zeta = I_p sqrt(rho k_s G) of a pipe (N m s/rad).

    Defaults: the paper's drill pipe (E = 210 GPa, nu = 0.29, k_s = 6/7): 410.6 N m s/rad.
    """
    polar = math.pi / 32.0 * (outer_m ** 4 - inner_m ** 4)
    return polar * math.sqrt(density * shear_factor * shear_pa)


class ImpedanceController(Node):
    """
    The impedance law on the twin's speed set-point, through topics (module docstring).

    :param reference_rad_per_s: omega_ref, the speed the driller asks for (rad/s).
    :param impedance_nm_s_per_rad: zeta (N m s/rad).
    :param mean_time_constant_s: tau_m of the mean torque filter (s).
    :param sample_period_s: the time between two torque readings (the twin's tick, s).
    :param filter_time_constant_s: a first-order low-pass on the torque reading (s; 0: none).
    :param switch_drive: send the dynamic mode and the stiff controller at start.
    :param start_at_s: the twin time from which it commands (s; before, it only listens).
    :param start_after_first_reading: count ``start_at_s`` from the first reading heard (a
        twin in real time stamps with the system clock) instead of from twin time 0.
    """

    def __init__(self, reference_rad_per_s: float, impedance_nm_s_per_rad: float,
                 mean_time_constant_s: float = 10.0, sample_period_s: float = 0.01,
                 filter_time_constant_s: float = 0.05, switch_drive: bool = True,
                 start_at_s: float = 0.0, start_after_first_reading: bool = False, **kwargs):
        super().__init__('impedance_controller', **kwargs)
        self.reference = float(reference_rad_per_s)
        self.impedance = float(impedance_nm_s_per_rad)
        self.weight = sample_period_s / (mean_time_constant_s + sample_period_s)
        self.filter_weight = sample_period_s / (filter_time_constant_s + sample_period_s)
        self.torque_nm = None
        self.mean_torque_nm = None
        self.speed_rad_per_s = None
        self.reading_stamp_ns = None
        self.sent = {}               # value -> (perf_counter, reading stamp, system time ns)
        self.latencies = []          # (wall round trip, reading to effect, publish to effect) s
        self.commands = 0
        reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        self.speed_command = self.create_publisher(Float64, CMD_TOP_DRIVE_SPEED, reliable)
        self.mode_command = self.create_publisher(String, CMD_TOP_DRIVE_MODE, reliable)
        self.controller_command = self.create_publisher(String, CMD_TOP_DRIVE_CONTROLLER,
                                                        reliable)
        # The top state first: an executor takes the ready subscriptions in the order they
        # were created, and the twin publishes the top state just before the readings of the
        # same tick, so the stamp noted is the reading's own.
        self.create_subscription(JointState, TOP_STATE, self._on_top_state, reliable)
        self.create_subscription(Float64, SURFACE_SPEED, self._on_speed, reliable)
        self.create_subscription(Float64, SURFACE_TORQUE, self._on_torque, reliable)
        self.create_subscription(JointState, APPLIED_TOP_DRIVE_SPEED, self._on_applied,
                                 reliable)
        self._switch_pending = switch_drive
        self.start_at_ns = int(round(start_at_s * 1e9))
        self._start_pending = start_after_first_reading

    def publishers_matched(self) -> bool:
        """Return True when the twin subscribes to every command this node sends."""
        return all(p.get_subscription_count() > 0 for p in
                   (self.speed_command, self.mode_command, self.controller_command))

    def _on_top_state(self, message: JointState) -> None:
        self.reading_stamp_ns = message.header.stamp.sec * 10 ** 9 + message.header.stamp.nanosec
        if self._start_pending:
            self.start_at_ns += self.reading_stamp_ns
            self._start_pending = False

    def _on_speed(self, message: Float64) -> None:
        self.speed_rad_per_s = message.data

    def _on_torque(self, message: Float64) -> None:
        if self.reading_stamp_ns is None or self.reading_stamp_ns < self.start_at_ns:
            return
        if self._switch_pending:
            self.mode_command.publish(String(data='dynamic'))
            self.controller_command.publish(String(data='stiff'))
            self._switch_pending = False
        if self.torque_nm is None:
            self.torque_nm = self.mean_torque_nm = message.data
        self.torque_nm += self.filter_weight * (message.data - self.torque_nm)
        torque = self.torque_nm
        self.mean_torque_nm += self.weight * (torque - self.mean_torque_nm)
        # The twin accepts set-points from 0 up (a drive does not reverse to damp).
        setpoint = max(self.reference - (torque - self.mean_torque_nm) / self.impedance, 0.0)
        self.sent[setpoint] = (time.perf_counter(), self.reading_stamp_ns, time.time_ns())
        self.speed_command.publish(Float64(data=setpoint))
        self.commands += 1

    def _on_applied(self, message: JointState) -> None:
        sent = self.sent.pop(message.position[0], None)
        if sent is None:
            return
        wall, reading_ns, published_ns = sent
        effect_ns = message.header.stamp.sec * 10 ** 9 + message.header.stamp.nanosec
        twin_s = (effect_ns - reading_ns) * 1e-9 if reading_ns is not None else math.nan
        self.latencies.append((time.perf_counter() - wall, twin_s,
                               (effect_ns - published_ns) * 1e-9))
        if len(self.sent) > 10000:                       # superseded ones are never echoed
            self.sent.clear()

    def latency_summary(self) -> str:
        """Return the median and 95th percentile of the latencies measured so far."""
        if not self.latencies:
            return 'no command echoed yet'
        wall = sorted(w for w, _, _ in self.latencies)
        twin = sorted(t for _, t, _ in self.latencies if not math.isnan(t))
        effect = sorted(e for _, _, e in self.latencies)

        def pct(values, p):
            return values[min(len(values) - 1, int(p * len(values)))] if values else math.nan
        return (f'{len(self.latencies)} commands echoed of {self.commands} sent: wall round '
                f'trip median {1e3 * pct(wall, 0.5):.2f} ms, 95 % {1e3 * pct(wall, 0.95):.2f} '
                f'ms; twin time from the reading to the effect median {1e3 * pct(twin, 0.5):.0f}'
                f' ms, 95 % {1e3 * pct(twin, 0.95):.0f} ms; from the publication to the effect '
                f'(the twin clock against this system clock: meaningful in real time) median '
                f'{1e3 * pct(effect, 0.5):.1f} ms, 95 % {1e3 * pct(effect, 0.95):.1f} ms')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--reference', type=float, default=5.215,
                        help='omega_ref, rad/s (default: the paper\'s 0.83 Hz)')
    parser.add_argument('--impedance', type=float, default=None,
                        help='zeta, N m s/rad (default: the paper\'s drill pipe)')
    parser.add_argument('--mean-time-constant', type=float, default=10.0)
    parser.add_argument('--sample-period', type=float, default=0.01)
    parser.add_argument('--torque-filter', type=float, default=0.05,
                        help='time constant of the low-pass on the torque reading, s')
    parser.add_argument('--start-at', type=float, default=0.0,
                        help='twin time from the first reading heard after which it commands, '
                             's (before, it only listens)')
    parser.add_argument('--duration', type=float, default=0.0,
                        help='wall seconds to run (0: until Ctrl-C)')
    args = parser.parse_args()
    rclpy.init()
    node = ImpedanceController(args.reference, args.impedance or pipe_impedance_nm_s_per_rad(),
                               args.mean_time_constant, args.sample_period,
                               args.torque_filter, start_at_s=args.start_at,
                               start_after_first_reading=True)
    end = time.monotonic() + args.duration if args.duration > 0 else math.inf
    try:
        while rclpy.ok() and time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        print(node.latency_summary())
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
