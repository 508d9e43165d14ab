"""The twin as an rclpy node: a thin boundary around :class:`~drill_twin.twin.engine.TwinEngine`.

A timer (``rate_hz``, 100 Hz by default) advances the engine by 1 / rate_hz of simulated time
in model sub-steps and publishes the results. A timer that fires late skips the periods it
missed, so a tick that finds the twin's clock behind the wall clock (a stall of the machine)
takes extra steps, at most as many again as a tick's, until it has caught up. With ``fast``
or ``use_sim_time`` it ticks as fast as it can and publishes /clock. Commands arrive on two Float64 topics and take effect on
the next model step. Every published message, the commands as applied and the twin's own log
lines are recorded to an MCAP log. Header stamps, /clock and the log times use the twin's
clock: the ROS time at start plus the simulated time (from zero in fast mode).
"""
from __future__ import annotations

import datetime
import sys
import time
from pathlib import Path

import rclpy
import yaml
from threadpoolctl import threadpool_limits
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy._rclpy_pybind11 import RCLError
from rclpy.exceptions import ParameterUninitializedException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from rclpy.task import Future
from std_msgs.msg import Float64

from drill_twin import __version__
from drill_twin import interface as itf
from drill_twin.config import ConfigError, load_config
from drill_twin.config.loader import config_to_dict
from drill_twin.recording.log_metadata import TwinLogMetadata
from drill_twin.recording.qos import rclpy_qos_profile
from drill_twin.recording.twin_log import TwinLog
from drill_twin.ros import messages
from drill_twin.ros.parameters import BY_NAME, PARAMETERS, unsafe_change_reason
from drill_twin.twin.engine import (CommandLimits, CommandRejected, EnsembleSettings,
                                    TwinEngine, TwinStalled)

FAST_PERIOD_S = 1e-6


class LogDirectoryError(RuntimeError):
    """The log cannot be written and ``on_log_error`` says exit."""


def _descriptor(spec) -> ParameterDescriptor:
    descriptor = ParameterDescriptor(description=spec.description)
    if spec.low is not None and isinstance(spec.default, int) and not isinstance(spec.default,
                                                                                  bool):
        descriptor.integer_range = [IntegerRange(from_value=int(spec.low),
                                                 to_value=int(spec.high), step=1)]
    elif spec.low is not None and isinstance(spec.default, float):
        descriptor.floating_point_range = [FloatingPointRange(from_value=float(spec.low),
                                                              to_value=float(spec.high))]
    if spec.choices:
        descriptor.additional_constraints = 'one of: ' + ', '.join(spec.choices)
    return descriptor


class TwinNode(Node):
    """The twin node (see the module docstring); ``done`` completes when it should stop."""

    def __init__(self, **kwargs):
        super().__init__(itf.NODE_NAME, **kwargs)
        for spec in PARAMETERS:
            default = Parameter.Type.STRING_ARRAY if spec.name == 'model_overrides' else spec.default
            self.declare_parameter(spec.name, default, _descriptor(spec))
        p = {spec.name: self._value(spec.name) for spec in PARAMETERS}
        p['model_overrides'] = [item for item in (p['model_overrides'] or []) if item]
        self.fast = bool(p['fast']) or bool(self.get_parameter('use_sim_time').value)
        if p['on_log_error'] not in BY_NAME['on_log_error'].choices:
            raise ConfigError('parameter', 'on_log_error',
                              f"must be 'continue' or 'exit', got {p['on_log_error']!r}")
        self.params = p
        overrides = list(p['model_overrides'])
        if p['time_step_s'] > 0:
            overrides.insert(0, f'integration.time_step_s={p["time_step_s"]!r}')
        self.config = load_config(p['model_config'] or None, overrides)
        self.engine = TwinEngine(
            self.config,
            EnsembleSettings(members=p['ensemble_members'], dispersion=p['ensemble_dispersion'],
                             seed=p['seed'], separate_process=p['ensemble_process']),
            self._limits(p), kpi_window_s=p['kpi_window_s'])
        self.log = None
        try:
            dt = self.engine.dt
            self.substeps = max(1, round(1.0 / (p['rate_hz'] * dt)))
            self.tick_s = self.substeps * dt
            self.dt_ns = int(round(dt * 1e9))
            self.stations_m = [s.x_m for s in self.engine.simulator.system.stations]
            self.ticks = 0
            self._pace_origin_ns = None
            self.failed = False
            self.done = Future()
            self._health_mark = (time.perf_counter(), 0.0)
            self._outputs = {}
            for topic, (type_, qos) in self._published_topics().items():
                self._outputs[topic] = self.create_publisher(type_, topic, rclpy_qos_profile(qos))
            command_qos = rclpy_qos_profile(itf.STATE_QOS)
            self.create_subscription(Float64, itf.CMD_TOP_DRIVE_SPEED, self._on_top_drive_speed,
                                     command_qos)
            self.create_subscription(Float64, itf.CMD_HOOK_LOAD, self._on_hook_load, command_qos)
            # The twin's clock starts as late as it can: the first tick should find it on time.
            self.epoch_ns = 0 if self.fast else self.get_clock().now().nanoseconds
            self.log = self._open_log(p) if p['log_enabled'] else None
            self.timer = self.create_timer(FAST_PERIOD_S if self.fast else 1.0 / p['rate_hz'],
                                           self._on_tick)
            self.add_on_set_parameters_callback(self._on_set_parameters)
            self._report('info', f'drill_twin {__version__}: {self.engine.ensemble.members} '
                         f'ensemble members (delta {p["ensemble_dispersion"]:g}, seed '
                         f'{p["seed"]}), {self.substeps} steps of {dt * 1e3:g} ms per tick, '
                         + ('fast, publishing /clock' if self.fast else f'{p["rate_hz"]:g} Hz')
                         + (f'; logging to {self.log.path}' if self.log else '; no log'))
        except BaseException:       # e.g. a signal while starting: stop the worker, finish the log
            self.close()
            raise

    # -- set-up --------------------------------------------------------------------------
    def _value(self, name: str):
        try:
            return self.get_parameter(name).value
        except ParameterUninitializedException:          # a string array left unset
            return None

    @staticmethod
    def _limits(p) -> CommandLimits:
        return CommandLimits(top_drive_speed_max_rad_per_s=p['top_drive_speed_max_rad_per_s'],
                             hook_load_min_n=p['hook_load_min_n'],
                             hook_load_max_n=p['hook_load_max_n'])

    def _published_topics(self):
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import Vector3Stamped, WrenchStamped
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import Imu, JointState
        from std_msgs.msg import Float64MultiArray

        state = itf.STATE_QOS
        topics = {itf.BIT_STATE: (JointState, state), itf.BIT_WRENCH: (WrenchStamped, state),
                  itf.TOP_STATE: (JointState, state),
                  itf.CONTACT_FORCES: (Float64MultiArray, state),
                  itf.KPI_STICK_SLIP: (Float64, state), itf.KPI_MSE: (Float64, state),
                  itf.KPI_ROP: (Float64, state),
                  itf.DIAGNOSTICS: (DiagnosticArray, itf.DIAGNOSTICS_QOS)}
        if self.engine.ensemble.members:
            for topic in (itf.ENSEMBLE_MEAN, itf.ENSEMBLE_LOWER, itf.ENSEMBLE_UPPER):
                topics[topic] = (JointState, state)
        for x_m in self.stations_m:
            topics[itf.vibration_imu_topic(x_m)] = (Imu, state)
            topics[itf.vibration_displacement_topic(x_m)] = (Vector3Stamped, state)
        if self.fast:
            topics[itf.CLOCK] = (Clock, itf.CLOCK_QOS)
        return topics

    log_error: str | None = None
    """Why the log stopped or could not be opened (None while it runs, or without a log)."""

    def _open_log(self, p):
        """Open the run's log, a rosbag2 bag ``log_dir/drill_twin_<UTC time>/``; None if it
        cannot be created and ``on_log_error`` is continue (LogDirectoryError if exit)."""
        stamp = datetime.datetime.now(datetime.timezone.utc).strftime('%Y%m%dT%H%M%SZ')
        path = Path(p['log_dir']) / f'drill_twin_{stamp}'
        counter = 1
        while path.exists():
            path = Path(p['log_dir']) / f'drill_twin_{stamp}_{counter}'
            counter += 1
        metadata = TwinLogMetadata(
            config_yaml=yaml.safe_dump(config_to_dict(self.config), sort_keys=False),
            seed=p['seed'], clock_epoch_ns=self.epoch_ns, time_step_s=self.engine.dt,
            ensemble_members=p['ensemble_members'],
            ensemble_dispersion=p['ensemble_dispersion'],
            ensemble_process=bool(p['ensemble_process']), rate_hz=p['rate_hz'],
            substeps=self.substeps, fast=self.fast, kpi_window_s=p['kpi_window_s'],
            version=__version__)
        try:
            return TwinLog(path, self.stations_m, metadata, split_duration_s=p['log_split_s'])
        except OSError as error:
            text = f'cannot write the log {path}: {error.strerror or error}'
            if p['on_log_error'] == 'exit':
                raise LogDirectoryError(text) from None
            self.log_error = text
            self.get_logger().error(text + '; running without a log (on_log_error: continue)')
            return None

    def _on_log_failure(self, now: int) -> None:
        """A write to the log failed (disk full, ...): the log is closed; say so as an ERROR
        on /rosout and /diagnostics, then obey ``on_log_error`` (exit: stop, status 1)."""
        error, self.log = self.log.error, None
        stop = self.params['on_log_error'] == 'exit'
        self.log_error = (error or 'the log was closed') + (
            '; stopping (on_log_error: exit)' if stop
            else '; the twin runs on without a log (on_log_error: continue)')
        self._report('error', self.log_error)
        self._publish(itf.DIAGNOSTICS, messages.health(
            {'log': 'stopped', 'log_error': self.log_error}, 'error',
            'the log stopped: ' + self.log_error, now), now)
        if stop:
            self.failed = True
            self.done.set_result(False)

    # -- time ----------------------------------------------------------------------------
    def twin_time_ns(self) -> int:
        """The twin's clock (ns): the epoch plus the simulated time."""
        return self.epoch_ns + self.engine.step_index * self.dt_ns

    # -- commands ------------------------------------------------------------------------
    def _on_top_drive_speed(self, message: Float64) -> None:
        self._command(itf.CMD_TOP_DRIVE_SPEED, message, self.engine.set_top_drive_speed)

    def _on_hook_load(self, message: Float64) -> None:
        self._command(itf.CMD_HOOK_LOAD, message, self.engine.set_hook_load)

    def _command(self, topic, message, apply) -> None:
        try:
            apply(message.data)
        except CommandRejected as error:
            self._report('warn', f'{topic}: {error}; the previous command stays')
            return
        if self.log:
            self.log.write(topic, message, self.twin_time_ns())    # takes effect at this time

    # -- the tick ------------------------------------------------------------------------
    def _on_tick(self) -> None:
        if self.done.done() or not self.context.ok():       # stopping: publish nothing more
            return
        if self.ticks == 0:                 # the real-time factor counts from the first tick
            self._health_mark = (time.perf_counter(), self.engine.time_s)
        try:
            snapshot = self.engine.advance(self._steps_this_tick())
        except TwinStalled as error:
            self._report('error', f'{error}; stopping')
            self.failed = True
            self.done.set_result(False)
            return
        self.ticks += 1
        now = self.twin_time_ns()
        self._publish(itf.BIT_STATE, messages.bit_state(snapshot.bit, now), now)
        self._publish(itf.BIT_WRENCH, messages.bit_wrench(snapshot.bit, now), now)
        self._publish(itf.TOP_STATE, messages.top_state(snapshot, now), now)
        self._publish(itf.CONTACT_FORCES, messages.contact_forces(snapshot), now)
        for topic, message in messages.station_messages(snapshot, self.stations_m, now):
            self._publish(topic, message, now)
        if self._due(self.params['kpi_rate_hz']):
            self._publish(itf.KPI_STICK_SLIP, messages.scalar(snapshot.stick_slip_severity), now)
            self._publish(itf.KPI_MSE, messages.scalar(snapshot.mse_pa), now)
            self._publish(itf.KPI_ROP, messages.scalar(snapshot.rop_m_per_h), now)
        if snapshot.ensemble_mean is not None and self._due(self.params['ensemble_rate_hz']):
            stamp = self.epoch_ns + snapshot.ensemble_step * self.dt_ns     # a tick behind
            for topic, state in ((itf.ENSEMBLE_MEAN, snapshot.ensemble_mean),
                                 (itf.ENSEMBLE_LOWER, snapshot.ensemble_lower),
                                 (itf.ENSEMBLE_UPPER, snapshot.ensemble_upper)):
                self._publish(topic, messages.bit_state(state, stamp), now)
        if snapshot.events:
            self._publish(itf.DIAGNOSTICS, messages.events(snapshot.events, now), now)
            for event in snapshot.events:
                if event.kind != 'command_rejected':            # already reported
                    self._report(event.level, event.message)
        if self._due(self.params['health_rate_hz']):
            self._publish_health(snapshot, now)
        if self.fast:
            self._publish(itf.CLOCK, messages.clock(now), now)
        if self.log and not self.log.open:          # a write failed (disk full, ...)
            self._on_log_failure(now)
            if self.done.done():                    # on_log_error: exit
                return
        duration = self.params['duration_s']
        if duration > 0 and self.engine.time_s >= duration - 0.5 * self.engine.dt:
            self._report('info', f'{duration:g} s simulated: stopping')
            self.done.set_result(True)

    def _steps_this_tick(self) -> int:
        """A tick's steps, plus up to as many again while the twin is behind the wall clock."""
        if self.fast:
            return self.substeps
        if self._pace_origin_ns is None:            # the first tick sets the pace
            self._pace_origin_ns = (self.get_clock().now().nanoseconds
                                    - self.substeps * self.dt_ns)
            return self.substeps
        behind = self._steps_behind_wall_clock() - self.substeps
        return self.substeps + min(max(behind, 0), self.substeps)

    def _steps_behind_wall_clock(self) -> int:
        """Whole model steps the twin has fallen behind the ROS clock since its first tick
        (real-time mode; the start-up before the first tick does not count)."""
        if self._pace_origin_ns is None:
            return 0
        elapsed = self.get_clock().now().nanoseconds - self._pace_origin_ns
        return elapsed // self.dt_ns - self.engine.step_index

    def _due(self, rate_hz: float) -> bool:
        every = max(1, round(1.0 / (rate_hz * self.tick_s)))
        return self.ticks % every == 0

    def _publish(self, topic: str, message, time_ns: int) -> None:
        data = serialize_message(message)           # once, for the wire and for the log
        try:
            self._outputs[topic].publish(data)
        except RCLError:
            if self.context.ok():
                raise
            return                                  # a signal shut the context down mid-tick
        if self.log:
            self.log.write_serialized(topic, data, time_ns)

    def _publish_health(self, snapshot, now: int) -> None:
        wall, simulated = time.perf_counter(), self.engine.time_s
        previous_wall, previous_simulated = self._health_mark
        self._health_mark = (wall, simulated)
        factor = (simulated - previous_simulated) / max(wall - previous_wall, 1e-9)
        h = snapshot.health
        lag_s = 0.0 if self.fast else self._steps_behind_wall_clock() * self.engine.dt
        behind = not self.fast and (factor < 0.95 or lag_s > 0.1)
        values = {'real_time_factor': f'{factor:.3f}', 'sim_time_s': f'{simulated:.3f}',
                  'behind_wall_clock_ms': f'{1e3 * max(lag_s, 0.0):.0f}',
                  'tick_time_ms': f'{1e3 * h["tick_wall_time_s"]:.2f}',
                  'tick_time_max_ms': f'{1e3 * h["tick_wall_time_max_s"]:.2f}',
                  'tick_period_ms': f'{1e3 * self.tick_s:.2f}',
                  'iterations_per_step': f'{h["iterations_per_step"]:.2f}',
                  'ensemble_iterations_per_step': f'{h["ensemble_iterations_per_step"]:.2f}',
                  'ensemble_tick_time_ms': f'{1e3 * h["ensemble_tick_wall_time_s"]:.2f}',
                  'members': h['members'], 'resets': h['resets'],
                  'rejected_commands': h['rejected_commands'],
                  'ensemble_members_touching_wall': h['ensemble_members_touching_wall'],
                  'ensemble_members_lifted_off': h['ensemble_members_lifted_off'],
                  'log': str(self.log.path) if self.log and self.log.open else 'none'}
        message = ('falling behind real time' if behind else 'running')
        self._publish(itf.DIAGNOSTICS, messages.health(values, 'warn' if behind else 'info',
                                                       message, now), now)
        if self.log:
            self.log.flush()

    def _report(self, level: str, text: str) -> None:
        """A log line to rosout, and to the MCAP log's /rosout."""
        # One call site per severity: rclpy keys a logger's call context by the calling line
        # and raises ValueError if the severity changes between calls from the same line.
        logger = self.get_logger()
        if level == 'error':
            logger.error(text)
        elif level == 'warn':
            logger.warning(text)
        else:
            logger.info(text)
        if self.log:
            now = self.twin_time_ns()
            self.log.write(itf.ROSOUT, messages.log(level, text, self.get_name(), now), now)

    # -- parameters at run time ----------------------------------------------------------
    def _on_set_parameters(self, parameters) -> SetParametersResult:
        for parameter in parameters:
            spec = BY_NAME.get(parameter.name)
            if parameter.name == 'use_sim_time' or (spec is not None and not spec.safe):
                return SetParametersResult(successful=False,
                                           reason=unsafe_change_reason(parameter.name))
            if spec is not None and spec.choices and parameter.value not in spec.choices:
                return SetParametersResult(successful=False, reason=(
                    f'{parameter.name} must be one of {", ".join(spec.choices)}'))
        updated = dict(self.params)
        updated.update({p.name: p.value for p in parameters if p.name in BY_NAME})
        if updated['hook_load_min_n'] > updated['hook_load_max_n']:
            return SetParametersResult(successful=False,
                                       reason='hook_load_min_n must not exceed hook_load_max_n')
        self.params = updated
        self.engine.limits = self._limits(updated)
        self.engine.kpi_window_s = float(updated['kpi_window_s'])
        return SetParametersResult(successful=True)

    # -- ending --------------------------------------------------------------------------
    def close(self) -> None:
        """Stop the ensemble worker and complete the log (safe to call twice)."""
        self.engine.close()
        if self.log:
            self.log.close()
            if self.log.error:                      # completing the log failed (disk full)
                self.get_logger().error(self.log.error)


def run(ros_args: list[str]) -> int:
    """Run the twin until ``duration_s`` or a signal (SIGINT, SIGTERM); return the status.

    BLAS is single-threaded for the node's whole life: the model's matrices are small (threads
    cost more than they save on this 2-core class of machine), and a run is then reproduced
    bit for bit by ``drill-twin replay --resimulate``.
    """
    with threadpool_limits(limits=1, user_api='blas'):
        return _run(ros_args)


def _run(ros_args: list[str]) -> int:
    from rclpy.exceptions import ParameterException

    def _first_line(error):
        return (str(error).strip().splitlines() or [type(error).__name__])[0]

    node = None
    executor = None
    status = 0
    try:
        try:
            rclpy.init(args=ros_args)
        except RCLError as error:
            print(f'drill-twin: ROS arguments: {_first_line(error)}', file=sys.stderr)
            return 2
        executor = SingleThreadedExecutor()
        node = TwinNode()
        executor.add_node(node)
        executor.spin_until_future_complete(node.done)
        if node.failed:
            status = 1                                 # the model stalled (reported)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RCLError:
        if rclpy.ok():
            raise
        # A signal shut the context down while the node was starting: a normal stop.
    except ParameterException as error:
        # Backstop: the command line checks every parameter before the node starts.
        print(f'drill-twin: parameter: {_first_line(error)}', file=sys.stderr)
        status = 2
    except LogDirectoryError as error:
        print(f'drill-twin: {error} (on_log_error: exit)', file=sys.stderr)
        status = 1
    finally:
        if node is not None:
            node.close()
            node.destroy_node()
        if executor is not None:
            executor.shutdown()
        rclpy.try_shutdown()
    return status
