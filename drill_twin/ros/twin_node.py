"""
The twin as an rclpy node: a thin boundary around :class:`~drill_twin.twin.engine.TwinEngine`.

The engine is built outside the node (:func:`create_twin_node`, :mod:`drill_twin.ros.build`)
and handed in with the :class:`~drill_twin.ros.parameters.TwinParameters` it was built from;
the node declares them as ROS parameters (:mod:`~drill_twin.ros.node_parameters`) and replaces
its frozen copy when a safe one changes. It wires publishers, subscriptions and timers, and
its callbacks call into one collaborator a concept:

- :mod:`~drill_twin.ros.clock`: a timer (``rate_hz``) advances the engine by the model steps
  whose time the wall clock has reached, never past it, catching up after a stall of the
  machine; with ``fast`` as fast as it can (publishing /clock); with ``use_sim_time`` to the
  latest external /clock, from the first one on.
- :mod:`~drill_twin.ros.commands`: commands (:data:`drill_twin.interface.COMMANDS`) act from
  the next model step; each applied one is echoed on ``/drill_twin/cmd_applied/<name>``
  stamped with the twin time of that step; counted, rejected, dropped and superseded.
- :mod:`~drill_twin.ros.measurements`: the rig's samples for the ensemble filter.
- :mod:`~drill_twin.ros.outputs`: the states and surface readings every tick, the KPIs and the
  driller's view, the ensemble, TF; a volatile topic only while a subscription matches it.
- :mod:`~drill_twin.ros.run_log`: the MCAP log of all of it and of the twin's own log lines.
- :mod:`~drill_twin.ros.diagnostics`: health, from a wall-clock timer of its own
  (``health_rate_hz``), so a twin whose clock stands still still reports.
- :mod:`~drill_twin.ros.watchers`: a rerun live view and a console status line, if asked for.

Header stamps, /clock and the log times use the twin's clock: the ROS time at start plus the
simulated time (from zero in fast mode, from the first /clock message with use_sim_time).
"""
from __future__ import annotations

import sys

import rclpy
from rcl_interfaces.msg import SetParametersResult
from rclpy._rclpy_pybind11 import RCLError, UnknownROSArgsError
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.exceptions import NotInitializedException, ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMessage
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, String
from threadpoolctl import threadpool_limits

from drill_twin import __version__
from drill_twin import interface as itf
from drill_twin.recording.qos import rclpy_qos_profile
from drill_twin.ros import messages, node_parameters
from drill_twin.ros.build import build_engine
from drill_twin.ros.clock import TwinClock
from drill_twin.ros.commands import CommandIntake
from drill_twin.ros.diagnostics import HealthPeriod
from drill_twin.ros.measurements import (MeasurementIntake, measurement_topics,
                                         scalar_measurement_topics)
from drill_twin.ros.outputs import Outputs
from drill_twin.ros.parameters import ParameterError, TwinParameters, validate_ros_arguments
from drill_twin.ros.run_log import LogDirectoryError, RunLog
from drill_twin.ros.signals import let_the_signal_handler_finish
from drill_twin.ros.stop_future import StopFuture
from drill_twin.ros.watchers import console_status, live_view, Watchers
from drill_twin.twin.engine import CommandRejected, TwinEngine, TwinStalled

__all__ = ['create_twin_node', 'LogDirectoryError', 'run', 'StopFuture', 'TwinNode']

FAST_PERIOD_S = 1e-6


class TwinNode(Node):
    """
    The twin node (see the module docstring); ``done`` completes when it should stop.

    :param engine: the built engine; the node owns it from here (:meth:`close` closes it).
    :param params: the parameters ``engine`` was built with; declared as the node's ROS
        parameters (they take precedence over ``parameter_overrides``).
    :param kwargs: for ``rclpy.node.Node`` (e.g. ``parameter_overrides`` with use_sim_time).
    """

    def __init__(self, engine: TwinEngine, params: TwinParameters, **kwargs):
        self.engine, self.params = engine, params
        self.run_log, self.watchers = RunLog(), Watchers()
        self.done, self.failed = StopFuture(), False
        super().__init__(itf.NODE_NAME, parameter_overrides=[
            *(kwargs.pop('parameter_overrides', None) or ()),
            *node_parameters.overrides(params)], **kwargs)
        try:
            node_parameters.declare(self)
            self.sim_time = bool(self.get_parameter('use_sim_time').value)
            pace = 'external' if self.sim_time else 'fast' if params.fast else 'wall'
            self.stations_m = [s.x_m for s in engine.simulator.system.stations]
            self.tf_enabled = messages.TFMessage is not None
            self.measurement_topics = measurement_topics(engine)
            self.scalar_measurement_topics = scalar_measurement_topics(engine)
            self.intake = CommandIntake(engine)
            topics = messages.publications(
                self.stations_m, ensemble=bool(engine.ensemble.members), clock=pace == 'fast',
                tf=self.tf_enabled, assimilation=engine.assimilating)
            # Publishers without rclpy's default QoS-event handlers: the executor waits on
            # two a publisher every turn, 10-17 % of a core at 100 Hz (benchmarks/twin_node.py).
            # A subscriber asking for an incompatible QoS is told by its own handlers; the
            # twin's subscriptions keep theirs (an incompatible controller is reported here).
            quiet = PublisherEventCallbacks(use_default_callbacks=False)
            self.outputs = Outputs(topics, {
                topic: self.create_publisher(type_, topic, rclpy_qos_profile(qos),
                                             event_callbacks=quiet)
                for topic, (type_, qos) in topics.items()}, self.run_log, self.context)
            self._subscribe()
            # The twin's clock starts as late as it can: the first tick should find it on time.
            self.clock = TwinClock(pace, engine.dt, params.rate_hz, lambda: engine.step_index,
                                   lambda: self.get_clock().now().nanoseconds)
            self.measurements = MeasurementIntake(engine, self.clock, self.run_log)
            self.health = HealthPeriod(
                engine, self.clock, self.intake, self.run_log, sim_time=self.sim_time,
                sensor_topics=[*self.measurement_topics, *self.scalar_measurement_topics])
            if params.log_enabled and self.clock.started:
                self._open_log()
            self.timer = self.create_timer(
                FAST_PERIOD_S if pace == 'fast' else 1.0 / params.rate_hz, self._on_tick,
                clock=Clock(clock_type=ClockType.STEADY_TIME) if self.sim_time else None)
            self.health_timer = self.create_timer(1.0 / params.health_rate_hz, self._on_health,
                                                  clock=Clock(clock_type=ClockType.STEADY_TIME))
            self.add_on_set_parameters_callback(self._on_set_parameters)
            self._report('info', self._start_line())
            if self.clock.started:
                self._publish_static_tf()
        except BaseException:       # e.g. a signal while starting: stop the worker, finish the log
            self.close()
            raise

    def _subscribe(self) -> None:
        """Subscribe to the commands, to /clock (use_sim_time) and to the rig's sensors."""
        command_qos = rclpy_qos_profile(itf.COMMAND_QOS)
        self.command_subscriptions = {
            topic: self.create_subscription(
                String if topic in itf.MODE_COMMANDS else Float64, topic,
                lambda message, info, t=topic: self._on_command(t, message, info), command_qos)
            for topic in itf.COMMANDS}
        if self.sim_time:
            self.create_subscription(ClockMessage, itf.CLOCK, self._on_clock,
                                     rclpy_qos_profile(itf.CLOCK_QOS))
        for topic, sensor in self.measurement_topics.items():
            self.create_subscription(
                JointState, topic, lambda message, t=topic, s=sensor:
                self.measurements.joint_state(s, t, message),
                rclpy_qos_profile(itf.MEASUREMENT_QOS))
        for topic, channel in self.scalar_measurement_topics.items():
            self.create_subscription(
                Float64, topic, lambda message, t=topic, c=channel:
                self.measurements.scalar(c, t, message), rclpy_qos_profile(itf.MEASUREMENT_QOS))

    @property
    def log(self):
        """The open :class:`~drill_twin.recording.twin_log.TwinLog`, or None."""
        return self.run_log.log

    # -- callbacks -----------------------------------------------------------------------------
    def _on_tick(self) -> None:
        if self.done.done() or not self.context.ok():       # stopping: publish nothing more
            return
        steps = self.clock.steps_due()
        effect_ns = self.clock.twin_time_ns()   # the start of the first step the commands act in
        applied = self.intake.applied()
        snapshot = self._advance(steps) if steps else None
        if snapshot is None:                # not due yet, or the model stalled (reported)
            return
        now = self.clock.twin_time_ns()
        states_logged = self.clock.states_due(now, self.params.log_state_rate_hz)
        for topic, value in applied.items():
            self.outputs.publish(itf.cmd_applied_topic(topic),
                                 messages.command_applied(topic, value, effect_ns), now)
        plan = self.clock.plan(snapshot, kpi_rate_hz=self.params.kpi_rate_hz,
                               ensemble_rate_hz=self.params.ensemble_rate_hz, tf=self.tf_enabled)
        self.outputs.publish_tick(snapshot, self.stations_m, now, plan, states_logged)
        self._after_tick(snapshot, now)

    def _advance(self, steps: int):
        """Step the engine; the snapshot, or None if the model stalled (then stopping)."""
        if self.clock.ticks == 0:           # the real-time factor counts from the first tick
            self.health.first_tick()
        try:
            snapshot = self.engine.advance(steps)
        except TwinStalled as error:
            self._fail('stalled', str(error), f'{error}; stopping', stop=True)
            return None
        self.clock.ticks += 1
        self.watchers.update(snapshot)
        self.health.stepped(snapshot)
        self.intake.stepped()
        return snapshot

    def _after_tick(self, snapshot, now: int) -> None:
        """Report the tick's events and analyses, notice a failed log, stop at ``duration_s``."""
        for event, console in self.health.events(snapshot):
            self._report(event.level, event.message, console)
        if snapshot.analyses:                       # the latest analysis's parameters
            for topic, message in messages.analysis_messages(snapshot.analyses[-1]):
                self.outputs.publish(topic, message, now)
        failure = self.run_log.failure(self.params.on_log_error)
        if failure:                                 # a write failed (disk full, ...)
            self._fail('log', 'the log stopped: ' + failure, failure,
                       stop=self.params.on_log_error == 'exit')
            if self.done.done():
                return
        duration = self.params.duration_s
        if duration > 0 and self.engine.time_s >= duration - 0.5 * self.engine.dt:
            self._report('info', f'{duration:g} s simulated: stopping')
            self._publish_health()                  # the last period's report
            self.done.set_result(True)

    def _on_command(self, topic: str, message, info) -> None:
        """Take a command (it acts from the next model step); log it, show it."""
        sequence = info.get('publication_sequence_number') if info else None
        self.intake.count_gap(topic, sequence,
                              self.command_subscriptions[topic].get_publisher_count)
        try:
            self.intake.take(topic, message.data)   # the engine counts it (received, rejected)
        except CommandRejected as error:
            self._report('warn', f'{topic}: {error}; the previous command stays')
            return
        self.run_log.command(topic, message, self.clock.started, self.clock.twin_time_ns())
        self.watchers.command(self.engine.time_s, topic, message.data)

    def _on_clock(self, message: ClockMessage) -> None:
        """Follow an external /clock (use_sim_time); the twin's clock starts at the first."""
        if not self.clock.external(message.clock.sec * 1_000_000_000 + message.clock.nanosec):
            return
        if self.params.log_enabled:
            self._open_log()
        self.run_log.clock_started(self.clock.epoch_ns)    # the commands that came before
        self._report('info', f'/clock started at {self.clock.epoch_ns * 1e-9:.3f} s: the twin '
                     f'follows it' + (f'; logging to {self.log.path}' if self.log else ''))
        self._publish_static_tf()

    def _on_health(self) -> None:
        if self.done.done() or not self.context.ok():
            return
        self._publish_health()

    def _on_set_parameters(self, parameters) -> SetParametersResult:
        updated, reason = node_parameters.changed(self.params, parameters)
        if updated is None:
            return SetParametersResult(successful=False, reason=reason)
        if updated.health_rate_hz != self.params.health_rate_hz:
            self.health_timer.timer_period_ns = int(round(1e9 / updated.health_rate_hz))
        node_parameters.apply(self.engine, self.params, updated)
        self.params = updated
        return SetParametersResult(successful=True)

    # -- what the callbacks share --------------------------------------------------------------
    def _publish_health(self) -> None:
        """Publish the health report of the period since the last one on /diagnostics."""
        for line in self.health.console_lines():
            self.get_logger().warning(line)
        report = self.health.report(self.params.log_enabled)
        now = self.clock.twin_time_ns()
        self.outputs.publish(itf.DIAGNOSTICS, messages.health_report(report, now), now)
        self.run_log.flush()

    def _publish_static_tf(self) -> None:
        if self.tf_enabled:
            now = self.clock.twin_time_ns()
            self.outputs.publish(itf.TF_STATIC, messages.tf(messages.static_transforms(
                self.stations_m, now)), now)

    def _fail(self, kind: str, note: str, line: str, stop: bool) -> None:
        """Report a failure at once (rosout, an ERROR health report); stop if ``stop``."""
        self.health.monitor.note('error', kind, note)
        self._report('error', line)
        self._publish_health()                      # at once, not at the next period
        if stop:
            self.failed = True
            self.done.set_result(False)

    def _report(self, level: str, text: str, console: bool = True) -> None:
        """Write a log line to rosout (unless not ``console``), the MCAP log and the view."""
        # One call site per severity: rclpy keys a logger's call context by the calling line
        # and raises ValueError if the severity changes between calls from the same line.
        logger = self.get_logger()
        if console:
            if level == 'error':
                logger.error(text)
            elif level == 'warn':
                logger.warning(text)
            else:
                logger.info(text)
        self.run_log.line(level, text, self.get_name(), self.clock.twin_time_ns())
        self.watchers.line(self.engine.time_s, text, level)

    def _open_log(self) -> None:
        """Open the run's log; if it cannot be, say so (``on_log_error``: continue)."""
        problem = self.run_log.open(self.params, self.engine, self.clock, self.stations_m,
                                    tf=self.tf_enabled, sensor_topics=(
                                        self.measurement_topics, self.scalar_measurement_topics))
        if problem:
            self.get_logger().error(problem)

    def _start_line(self) -> str:
        p = self.params
        pace = ('fast, publishing /clock' if self.clock.fast else
                'following /clock (use_sim_time)' if self.sim_time else f'{p.rate_hz:g} Hz')
        where = (f'logging to {self.log.path}' if self.log else
                 'logging from the first /clock' if p.log_enabled and self.sim_time
                 else 'no log')
        topics = [*self.measurement_topics, *self.scalar_measurement_topics]
        assimilating = (f', assimilating {", ".join(topics)}' if topics else '')
        return (f'drill_twin {__version__}: {self.engine.ensemble.members} ensemble members '
                f'(delta {self.engine.ensemble.dispersion:g}, seed {p.seed}){assimilating}, '
                f'{self.clock.substeps} steps of {self.engine.dt * 1e3:g} ms per tick, {pace}; '
                f'{where}' + ('' if self.tf_enabled else '; no TF (tf2_msgs is not installed)'))

    def close(self) -> None:
        """Stop the ensemble worker and complete the log (safe to call twice)."""
        self.engine.close()
        error = self.run_log.close()
        if error:                                   # completing the log failed (disk full)
            self.get_logger().error(error)


def create_twin_node(params: TwinParameters, node_class=None, **kwargs) -> TwinNode:
    """
    Build the engine ``params`` describe and the node around it.

    A ``node_class`` (default TwinNode, or a subclass), ``kwargs`` for ``rclpy.node.Node``.
    Raises ConfigError on a bad model configuration.
    """
    engine = build_engine(params)
    try:
        return (node_class or TwinNode)(engine, params, **kwargs)
    except BaseException:
        engine.close()
        raise


def run(ros_args: list[str], view: str | None = None, console: bool | None = None) -> int:
    """
    Run the twin until ``duration_s`` or a signal (SIGINT, SIGTERM); return the status.

    ``view``: 'native' or 'web' streams the twin to a rerun viewer on 127.0.0.1 (the tabs of
    ``drill-twin view``); ``console``: a status line once a second and a summary at exit on
    stderr (default: when stderr is a terminal).

    BLAS is single-threaded for the node's whole life: the model's matrices are small (threads
    cost more than they save on this 2-core class of machine), and a run is then reproduced
    bit for bit by ``drill-twin replay --resimulate``.
    """
    with threadpool_limits(limits=1, user_api='blas'):
        return _run(ros_args, view, sys.stderr.isatty() if console is None else console)


def _first_line(error) -> str:
    return (str(error).strip().splitlines() or [type(error).__name__])[0]


def _run(ros_args: list[str], view: str | None = None, console: bool = False) -> int:
    node = executor = None
    status, interrupted = 0, False
    try:
        try:
            rclpy.init(args=ros_args)
        except (RCLError, UnknownROSArgsError) as error:    # the latter no RCLError
            kind = 'unknown ' if isinstance(error, UnknownROSArgsError) else ''
            print(f'drill-twin: ROS arguments: {kind}{_first_line(error)}', file=sys.stderr)
            return 2
        try:
            params = TwinParameters.from_values(validate_ros_arguments(ros_args))
        except ParameterError as error:
            print(f'drill-twin: parameter: {error}', file=sys.stderr)
            return 2
        executor = SingleThreadedExecutor()
        node = create_twin_node(params)
        node.watchers = Watchers(live_view(node.engine, node.stations_m, web=view == 'web')
                                 if view else None, console_status() if console else None)
        executor.add_node(node)
        executor.spin_until_future_complete(node.done)
        if node.failed:
            status = 1                                 # the model stalled (reported)
    except (KeyboardInterrupt, ExternalShutdownException):
        interrupted = True
    except (RCLError, NotInitializedException):
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
        if interrupted:
            let_the_signal_handler_finish()
        if node is not None:
            node.watchers.finish(str(node.log.path) if node.log else None, interrupted)
            node.close()
            node.destroy_node()
        if executor is not None:
            executor.shutdown()
        rclpy.try_shutdown()
    return status
