"""The twin as an rclpy node: a thin boundary around :class:`~drill_twin.twin.engine.TwinEngine`.

A timer (``rate_hz``, 100 Hz by default) advances the engine by the model steps whose time the
wall clock has reached, and publishes the results: the twin's clock never runs ahead of the
wall clock. A tick normally takes 1 / rate_hz of simulated time; a step longer than a tick
(``time_step_s`` > 1 / rate_hz) is taken by the tick that reaches it (the ticks between take
none and publish nothing); a tick that finds the twin behind the wall clock (a stall of the
machine) takes extra steps, at most as many again as a tick's, until it has caught up. With
``fast`` or ``use_sim_time`` it ticks as fast as it can and publishes /clock. Commands arrive
on two Float64 topics and take effect on the next model step; they are counted on arrival,
with those rejected, dropped (gaps in the publisher's sequence numbers) and superseded (a
later command arrived before the tick). Health is reported from a wall-clock timer of its own
(``health_rate_hz``), so a twin whose clock stands still still reports. Every published
message, the commands as applied and the twin's own log lines are recorded to an MCAP log.
Header stamps, /clock and the log times use the twin's clock: the ROS time at start plus the
simulated time (from zero in fast mode).
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
from rclpy.clock import Clock, ClockType
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
from drill_twin.twin.health import HealthMonitor

FAST_PERIOD_S = 1e-6
FROZEN_AFTER_S = 1.0
"""Wall time without a step after which health warns that the twin's clock stands still (s)."""


class StopFuture(Future):
    """The node's ``done`` future, registering each distinct done callback once.

    rclpy 7.1 (Jazzy) adds a fresh ``lambda x: self.wake()`` to the awaited future on every
    turn of ``Executor.spin_until_future_complete`` (ros2/rclpy#1374, #1702): a future awaited
    for hours collects one closure per tick, about 200 bytes, the node's whole memory growth
    (1.2 MB/min at 100 Hz, issue 9). Callbacks of the same code and the same captured objects
    do the same thing; the first one is kept, the repeats are dropped.
    """

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._registered = set()

    def add_done_callback(self, callback):
        code = getattr(callback, '__code__', None)
        if code is not None and self._pending():
            cells = tuple(id(cell.cell_contents) for cell in callback.__closure__ or ())
            key = (code, cells)
            if key in self._registered:
                return
            self._registered.add(key)
        super().add_done_callback(callback)


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
            self.done = StopFuture()
            self._health_mark = (time.perf_counter(), 0.0)
            self._advanced_at = time.monotonic()    # the last tick that took steps
            self.monitor = HealthMonitor()
            self._latest_health = {}
            self.commands_superseded = 0
            self.commands_dropped = 0
            self._pending_commands = set()          # accepted since the last tick
            self._sequence = {}                     # last publication sequence number, by topic
            self._outputs = {}
            for topic, (type_, qos) in self._published_topics().items():
                self._outputs[topic] = self.create_publisher(type_, topic, rclpy_qos_profile(qos))
            command_qos = rclpy_qos_profile(itf.COMMAND_QOS)
            self._commands = {
                topic: self.create_subscription(Float64, topic, callback, command_qos)
                for topic, callback in ((itf.CMD_TOP_DRIVE_SPEED, self._on_top_drive_speed),
                                        (itf.CMD_HOOK_LOAD, self._on_hook_load))}
            # The twin's clock starts as late as it can: the first tick should find it on time.
            self.epoch_ns = 0 if self.fast else self.get_clock().now().nanoseconds
            self.log = self._open_log(p) if p['log_enabled'] else None
            self.timer = self.create_timer(FAST_PERIOD_S if self.fast else 1.0 / p['rate_hz'],
                                           self._on_tick)
            self.health_timer = self.create_timer(1.0 / p['health_rate_hz'], self._on_health,
                                                  clock=Clock(clock_type=ClockType.STEADY_TIME))
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
                  itf.HOLE_DEPTH: (Float64, state),
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
    _log_stopped = False
    live_view = None
    """A :class:`~drill_twin.recording.live_view.LiveView` streaming to rerun, or None."""
    status = None
    """A :class:`~drill_twin.cli.console.StatusPrinter` for a terminal, or None."""
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
        self._log_stopped = True
        self.log_error = (error or 'the log was closed') + (
            '; stopping (on_log_error: exit)' if stop
            else '; the twin runs on without a log (on_log_error: continue)')
        self._report('error', self.log_error)
        self.monitor.note('error', 'log', 'the log stopped: ' + self.log_error)
        self._publish_health()                      # at once, not at the next period
        if stop:
            self.failed = True
            self.done.set_result(False)

    # -- time ----------------------------------------------------------------------------
    def twin_time_ns(self) -> int:
        """The twin's clock (ns): the epoch plus the simulated time."""
        return self.epoch_ns + self.engine.step_index * self.dt_ns

    # -- commands ------------------------------------------------------------------------
    def _on_top_drive_speed(self, message: Float64, info) -> None:
        self._command(itf.CMD_TOP_DRIVE_SPEED, message, info, self.engine.set_top_drive_speed)

    def _on_hook_load(self, message: Float64, info) -> None:
        self._command(itf.CMD_HOOK_LOAD, message, info, self.engine.set_hook_load)

    def _command(self, topic, message, info, apply) -> None:
        self._count_dropped(topic, info)
        try:
            apply(message.data)                     # counts it (received, rejected)
        except CommandRejected as error:
            self._report('warn', f'{topic}: {error}; the previous command stays')
            return
        if topic in self._pending_commands:         # the previous one never took effect
            self.commands_superseded += 1
        self._pending_commands.add(topic)
        if self.log:
            self.log.write(topic, message, self.twin_time_ns())    # takes effect at this time
        if self.live_view:
            key = ('top_drive_speed_rad_per_s' if topic == itf.CMD_TOP_DRIVE_SPEED
                   else 'hook_load_n')
            self.live_view.command(self.engine.time_s, **{key: message.data})

    def _count_dropped(self, topic: str, info) -> None:
        """Commands lost on the way: gaps in the publisher's sequence numbers (counted while
        one publisher sends the topic: the numbers of several publishers interleave)."""
        sequence = info.get('publication_sequence_number') if info else None
        if sequence is None:
            return
        last = self._sequence.get(topic)
        if (last is not None and sequence > last + 1
                and self._commands[topic].get_publisher_count() == 1):
            self.commands_dropped += sequence - last - 1
        self._sequence[topic] = sequence

    # -- the tick ------------------------------------------------------------------------
    def _on_tick(self) -> None:
        if self.done.done() or not self.context.ok():       # stopping: publish nothing more
            return
        steps = self._steps_this_tick()
        if steps == 0:                      # the wall clock has not reached the next step
            return
        if self.ticks == 0:                 # the real-time factor counts from the first tick
            self._health_mark = (time.perf_counter(), self.engine.time_s)
        try:
            snapshot = self.engine.advance(steps)
        except TwinStalled as error:
            self._stalled(error)
            return
        self.ticks += 1
        if self.live_view:
            self.live_view.update(snapshot)
        if self.status:
            self.status.update(snapshot)
        self._advanced_at = time.monotonic()
        self._pending_commands.clear()
        self._latest_health = snapshot.health
        self.monitor.observe_events(snapshot.events)
        now = self.twin_time_ns()
        for topic, message in messages.tick_messages(snapshot, self.stations_m, now):
            self._publish(topic, message, now)
        if self._due(self.params['kpi_rate_hz']):
            for topic, message in messages.kpi_messages(snapshot):
                self._publish(topic, message, now)
        if snapshot.ensemble_mean is not None and self._due(self.params['ensemble_rate_hz']):
            stamp = self.epoch_ns + snapshot.ensemble_step * self.dt_ns     # a tick behind
            for topic, message in messages.ensemble_messages(snapshot, stamp):
                self._publish(topic, message, now)
        if snapshot.events:
            self._publish(itf.DIAGNOSTICS, messages.events(snapshot.events, now), now)
            for event in snapshot.events:
                if event.kind != 'command_rejected':            # already reported
                    self._report(event.level, event.message)
        if self.fast:
            self._publish(itf.CLOCK, messages.clock(now), now)
        if self.log and not self.log.open:          # a write failed (disk full, ...)
            self._on_log_failure(now)
            if self.done.done():                    # on_log_error: exit
                return
        duration = self.params['duration_s']
        if duration > 0 and self.engine.time_s >= duration - 0.5 * self.engine.dt:
            self._report('info', f'{duration:g} s simulated: stopping')
            self._publish_health()                  # the last period's report
            self.done.set_result(True)

    def _steps_this_tick(self) -> int:
        """Fast: a tick's steps. Real time: the steps whose time the wall clock has reached,
        at most as many again as a tick's while catching up, so the twin's clock (epoch plus
        simulated time) never runs ahead of the wall clock."""
        if self.fast:
            return self.substeps
        now = self.get_clock().now().nanoseconds
        if self._pace_origin_ns is None:
            # The start-up before the first tick does not count; never earlier than the epoch.
            self._pace_origin_ns = max(self.epoch_ns, now - self.substeps * self.dt_ns)
        due = (now - self._pace_origin_ns) // self.dt_ns - self.engine.step_index
        return int(min(max(due, 0), 2 * self.substeps))

    def _stalled(self, error: TwinStalled) -> None:
        """The model cannot go on: report it (rosout and an ERROR health status), stop."""
        self.monitor.note('error', 'stalled', str(error))
        self._report('error', f'{error}; stopping')
        self._publish_health()
        self.failed = True
        self.done.set_result(False)

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

    def _on_health(self) -> None:
        if self.done.done() or not self.context.ok():
            return
        self._publish_health()

    def _publish_health(self) -> None:
        """The health report of the period since the last one, on /diagnostics."""
        values = self._health_values()
        counters = dict(self._latest_health, commands_dropped=self.commands_dropped)
        report = self.monitor.report(counters, values)
        now = self.twin_time_ns()
        self._publish(itf.DIAGNOSTICS, messages.health_report(report, now), now)
        if self.log:
            self.log.flush()

    def _health_values(self) -> dict:
        """The figures of a health report; notes lag and a missing log in the monitor."""
        wall, simulated = time.perf_counter(), self.engine.time_s
        previous_wall, previous_simulated = self._health_mark
        self._health_mark = (wall, simulated)
        factor = (simulated - previous_simulated) / max(wall - previous_wall, 1e-9)
        h = self._latest_health
        lag_s = 0.0 if self.fast else self._steps_behind_wall_clock() * self.engine.dt
        if not self.fast and self.ticks and (factor < 0.95 or lag_s > 0.1):
            self.monitor.note('warn', 'lag', f'falling behind real time ({1e3 * lag_s:.0f} ms '
                              f'behind the wall clock, real-time factor {factor:.3f})')
        still = time.monotonic() - self._advanced_at
        if self.ticks and still > FROZEN_AFTER_S:
            self.monitor.note('warn', 'frozen', f'the twin\'s clock has not advanced for '
                              f'{still:.1f} s')
        logging = bool(self.log and self.log.open)
        if self.params['log_enabled'] and not logging:
            self.monitor.note('warn', 'log', 'no log is being written (it could not be opened '
                              'or a write failed; the twin runs on without it)')
        values = {'real_time_factor': f'{factor:.3f}', 'sim_time_s': f'{simulated:.3f}',
                  'behind_wall_clock_ms': f'{1e3 * max(lag_s, 0.0):.0f}',
                  'tick_period_ms': f'{1e3 * self.tick_s:.2f}',
                  'commands_received': self.engine.commands_received,
                  'commands_dropped': self.commands_dropped,
                  'commands_superseded': self.commands_superseded,
                  'log': str(self.log.path) if logging else (
                      'stopped' if self._log_stopped else 'none')}
        for key, scale, unit in (('tick_wall_time_s', 1e3, 'tick_time_ms'),
                                 ('tick_wall_time_max_s', 1e3, 'tick_time_max_ms'),
                                 ('ensemble_tick_wall_time_s', 1e3, 'ensemble_tick_time_ms')):
            values[unit] = f'{scale * h.get(key, 0.0):.2f}'
        for key in ('iterations_per_step', 'ensemble_iterations_per_step'):
            values[key] = f'{h.get(key, 0.0):.2f}'
        for key in ('members', 'resets', 'rejected_commands', 'mean_model_resets',
                    'mean_model_failed_steps', 'mean_model_implausible_steps',
                    'ensemble_resets', 'retries', 'ensemble_members_touching_wall',
                    'ensemble_members_lifted_off'):
            values[key] = h.get(key, 0)
        return values

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
        if self.live_view:
            self.live_view.log_line(self.engine.time_s, text, level)

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
        if updated['health_rate_hz'] != self.params['health_rate_hz']:
            self.health_timer.timer_period_ns = int(round(1e9 / updated['health_rate_hz']))
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


def run(ros_args: list[str], view: str | None = None, console: bool | None = None) -> int:
    """Run the twin until ``duration_s`` or a signal (SIGINT, SIGTERM); return the status.

    ``view``: 'native' or 'web' streams the twin to a rerun viewer on 127.0.0.1 (the tabs of
    ``drill-twin view``); ``console``: a status line once a second and a summary at exit on
    stderr (default: when stderr is a terminal).

    BLAS is single-threaded for the node's whole life: the model's matrices are small (threads
    cost more than they save on this 2-core class of machine), and a run is then reproduced
    bit for bit by ``drill-twin replay --resimulate``.
    """
    with threadpool_limits(limits=1, user_api='blas'):
        return _run(ros_args, view, sys.stderr.isatty() if console is None else console)


def _run(ros_args: list[str], view: str | None = None, console: bool = False) -> int:
    from rclpy.exceptions import ParameterException

    def _first_line(error):
        return (str(error).strip().splitlines() or [type(error).__name__])[0]

    node = None
    executor = None
    status = 0
    interrupted = False
    try:
        try:
            rclpy.init(args=ros_args)
        except RCLError as error:
            print(f'drill-twin: ROS arguments: {_first_line(error)}', file=sys.stderr)
            return 2
        executor = SingleThreadedExecutor()
        node = TwinNode()
        if view:
            from drill_twin.recording.live_view import LiveView
            node.live_view = LiveView(node.stations_m, node.config)
            node.live_view.spawn_viewer(web=(view == 'web'))
        if console:
            from drill_twin.cli.console import StatusPrinter
            node.status = StatusPrinter(sys.stderr)
        executor.add_node(node)
        executor.spin_until_future_complete(node.done)
        if node.failed:
            status = 1                                 # the model stalled (reported)
    except (KeyboardInterrupt, ExternalShutdownException):
        interrupted = True
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
            if node.live_view:
                node.live_view.close()                 # the viewer keeps running for the user
            if node.status:
                node.status.finish(log_path=str(node.log.path) if node.log else None,
                                   reason='interrupted' if interrupted else 'stopped')
            node.close()
            node.destroy_node()
        if executor is not None:
            executor.shutdown()
        rclpy.try_shutdown()
    return status
