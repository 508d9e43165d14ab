"""
The twin as an rclpy node: a thin boundary around :class:`~drill_twin.twin.engine.TwinEngine`.

The engine is built outside the node (:func:`create_twin_node`, :mod:`drill_twin.ros.build`)
and handed in with the :class:`~drill_twin.ros.parameters.TwinParameters` it was built from;
the node declares them as ROS parameters and replaces its frozen copy when a safe one changes.

A timer (``rate_hz``, 100 Hz by default) advances the engine by the model steps whose time the
wall clock has reached, and publishes the results: the twin's clock never runs ahead of the
wall clock. A tick normally takes 1 / rate_hz of simulated time; a step longer than a tick
(``time_step_s`` > 1 / rate_hz) is taken by the tick that reaches it (the ticks between take
none and publish nothing); a tick that finds the twin behind the wall clock (a stall of the
machine) takes extra steps, at most as many again as a tick's, until it has caught up
(:mod:`drill_twin.ros.pacing`). With ``fast`` it ticks as fast as it can and publishes /clock.
With ``use_sim_time`` it follows an external /clock (a simulator, a bag player): its clock
starts at the first /clock message, each tick steps to the latest one, and it publishes no
/clock. TF (/tf_static once, /tf at ``kpi_rate_hz``) where tf2_msgs is installed. Commands arrive
on their topics (Float64 values, String modes: :data:`drill_twin.interface.COMMANDS`) and take
effect on the next model step; each applied one is echoed on ``/drill_twin/cmd_applied/<name>``
stamped with the twin time of that step. They are counted on arrival, with those rejected,
dropped (gaps in the publisher's sequence numbers) and superseded (a later command arrived
before the tick). The surface readings are published every tick, the driller's view (WITS
names, drilling units) with the KPIs. Health is reported from a wall-clock timer of its own
(``health_rate_hz``), so a twin whose clock stands still still reports. Every published
message, the commands as applied and the twin's own log lines are recorded to an MCAP log; a
volatile topic is sent only while a subscription matches it (:meth:`TwinNode._publish`), and a
tick builds its states only for a subscriber or the log.
Header stamps, /clock and the log times use the twin's clock: the ROS time at start plus the
simulated time (from zero in fast mode, from the first /clock message with use_sim_time).
"""
from __future__ import annotations

import math
import sys
import time

import rclpy
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy._rclpy_pybind11 import RCLError
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from rclpy.task import Future
from rosgraph_msgs.msg import Clock as ClockMessage
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, String
from threadpoolctl import threadpool_limits

from drill_twin import __version__
from drill_twin import interface as itf
from drill_twin.assimilation.measurements import SENSOR_CHANNELS, values_from_joint_state
from drill_twin.assimilation.sequential import Sample
from drill_twin.assimilation.settings import SENSOR_OF
from drill_twin.recording.qos import rclpy_qos_profile
from drill_twin.ros import messages
from drill_twin.ros.build import (build_engine, command_limits, log_metadata, new_log_path,
                                  open_log)
from drill_twin.ros.pacing import Pacer
from drill_twin.ros.parameters import (BY_NAME, ParameterError, PARAMETERS, TwinParameters,
                                       unsafe_change_reason, validate_ros_arguments)
from drill_twin.twin.engine import CommandRejected, TwinEngine, TwinStalled
from drill_twin.twin.health import HealthMonitor

_ENGINE_COMMANDS = {
    itf.CMD_TOP_DRIVE_SPEED: 'set_top_drive_speed', itf.CMD_HOOK_LOAD: 'set_hook_load',
    itf.CMD_TOP_DRIVE_MODE: 'set_top_drive_mode',
    itf.CMD_TOP_DRIVE_CONTROLLER: 'set_top_drive_controller',
    itf.CMD_TOP_DRIVE_TORQUE_LIMIT: 'set_top_drive_torque_limit',
    itf.CMD_AXIAL_MODE: 'set_axial_mode', itf.CMD_BLOCK_VELOCITY: 'set_block_velocity',
    itf.CMD_WOB_SETPOINT: 'set_weight_on_bit_setpoint'}
"""Command topic -> the TwinEngine method that checks and applies it."""
_LIVE_VIEW_KEYS = {itf.CMD_TOP_DRIVE_SPEED: 'top_drive_speed_rad_per_s',
                   itf.CMD_HOOK_LOAD: 'hook_load_n'}

FAST_PERIOD_S = 1e-6
FROZEN_AFTER_S = 1.0
"""Wall time without a step after which health warns that the twin's clock stands still (s)."""
WALL_CONTACT_EVENTS = ('impact', 'contact_end')
"""Events kept off the console (each one still on /diagnostics and in the log's /rosout); the
impacts are counted there once a health period."""
QUIET_EVENTS = WALL_CONTACT_EVENTS + ('measurement_rejected',)
"""Events that can come tens of times a second (contacts, a rig sending bad samples): on
/diagnostics and in the log's /rosout, counted on the console once a health period."""
NIS_WARN_PER_MEASUREMENT = 4.0
"""Mean normalised innovation squared per measured value over a health period above which
health warns (expected 1 when the filter's statistics are right; 4 is far outside the spread
of a period's few analyses)."""


class StopFuture(Future):
    """
    The node's ``done`` future, registering each distinct done callback once.

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


_PARAMETER_TYPES = {bool: Parameter.Type.BOOL, int: Parameter.Type.INTEGER,
                    float: Parameter.Type.DOUBLE, str: Parameter.Type.STRING,
                    tuple: Parameter.Type.STRING_ARRAY}


def _parameter(spec, value) -> Parameter:
    """Return the ROS parameter ``spec.name`` holding ``value``, typed as its default."""
    kind = _PARAMETER_TYPES[type(spec.default)]
    return Parameter(spec.name, kind, list(value) if isinstance(value, tuple) else value)


def _descriptor(spec) -> ParameterDescriptor:
    descriptor = ParameterDescriptor(description=spec.description)
    integer = isinstance(spec.default, int) and not isinstance(spec.default, bool)
    if spec.low is not None and integer:
        descriptor.integer_range = [IntegerRange(from_value=int(spec.low),
                                                 to_value=int(spec.high), step=1)]
    elif spec.low is not None and isinstance(spec.default, float):
        descriptor.floating_point_range = [FloatingPointRange(from_value=float(spec.low),
                                                              to_value=float(spec.high))]
    if spec.choices:
        descriptor.additional_constraints = 'one of: ' + ', '.join(spec.choices)
    return descriptor


class TwinNode(Node):
    """
    The twin node (see the module docstring); ``done`` completes when it should stop.

    :param engine: the built engine; the node owns it from here (:meth:`close` closes it).
    :param params: the parameters ``engine`` was built with; declared as the node's ROS
        parameters (they take precedence over ``parameter_overrides``).
    :param kwargs: for ``rclpy.node.Node`` (e.g. ``parameter_overrides`` with use_sim_time).
    """

    log = None
    log_error: str | None = None
    """Why the log stopped or could not be opened (None while it runs, or without a log)."""
    _log_stopped = False
    live_view = None
    """A :class:`~drill_twin.viz.live_view.LiveView` streaming to rerun, or None."""
    status = None
    """A :class:`~drill_twin.viz.console.StatusPrinter` for a terminal, or None."""

    def __init__(self, engine: TwinEngine, params: TwinParameters, **kwargs):
        self.engine = engine
        overrides = list(kwargs.pop('parameter_overrides', None) or ())
        # (rclpy cannot override with an empty array: such a parameter is left unset.)
        overrides += [_parameter(spec, getattr(params, spec.name)) for spec in PARAMETERS
                      if getattr(params, spec.name) != ()]
        super().__init__(itf.NODE_NAME, parameter_overrides=overrides, **kwargs)
        try:
            for spec in PARAMETERS:
                default = (Parameter.Type.STRING_ARRAY if isinstance(spec.default, tuple)
                           else spec.default)
                self.declare_parameter(spec.name, default, _descriptor(spec))
            self.params = params
            self.sim_time = bool(self.get_parameter('use_sim_time').value)
            self.fast = bool(params.fast) and not self.sim_time
            self._set_up_timing()
            self.tf_enabled = messages.TFMessage is not None
            # Without rclpy's default QoS-event handlers: the executor puts every handler in
            # its wait set at every turn, two a publisher, and over the twin's 40 publishers
            # that cost 10-17 % of a core at 100 Hz (benchmarks/twin_node.py). A subscriber
            # that asks for an incompatible QoS or type is told by its own handlers; the
            # twin's subscriptions keep theirs (a controller that offers an incompatible QoS
            # is reported here).
            quiet = PublisherEventCallbacks(use_default_callbacks=False)
            published = self._published_topics()
            self._outputs = {topic: self.create_publisher(type_, topic, rclpy_qos_profile(qos),
                                                          event_callbacks=quiet)
                             for topic, (type_, qos) in published.items()}
            self._durable = {topic for topic, (_, qos) in published.items()
                             if qos.durability == 'transient_local'}
            self._subscribe()
            # The twin's clock starts as late as it can: the first tick should find it on time.
            pace = 'external' if self.sim_time else 'fast' if self.fast else 'wall'
            self.pacer = Pacer(pace, self.dt_ns, self.substeps, None if self.sim_time else
                               0 if self.fast else self.get_clock().now().nanoseconds)
            if params.log_enabled and self.pacer.started:
                self.log = self._open_log()
            self.timer = self.create_timer(
                FAST_PERIOD_S if self.fast else 1.0 / params.rate_hz, self._on_tick,
                clock=Clock(clock_type=ClockType.STEADY_TIME) if self.sim_time else None)
            self.health_timer = self.create_timer(1.0 / params.health_rate_hz, self._on_health,
                                                  clock=Clock(clock_type=ClockType.STEADY_TIME))
            self.add_on_set_parameters_callback(self._on_set_parameters)
            self._report('info', self._start_line())
            if self.pacer.started:
                self._publish_static_tf()
        except BaseException:       # e.g. a signal while starting: stop the worker, finish the log
            self.close()
            raise

    # -- set-up --------------------------------------------------------------------------
    def _set_up_timing(self) -> None:
        dt = self.engine.dt
        self.substeps = max(1, round(1.0 / (self.params.rate_hz * dt)))
        self.tick_s = self.substeps * dt
        self._next_state_log_ns = None             # twin time of the next logged states
        self.dt_ns = int(round(dt * 1e9))
        self.stations_m = [s.x_m for s in self.engine.simulator.system.stations]
        self.ticks = 0
        self.failed = False
        self.done = StopFuture()
        self._health_mark = (time.perf_counter(), 0.0)
        self._advanced_at = time.monotonic()    # the last tick that took steps
        self.monitor = HealthMonitor()
        self._latest_health = {}
        self._impacts_unreported = 0
        self._refused_unreported = 0
        self._innovations = []                  # (NIS, measured values) of the health period
        self._measurements_at_report = 0
        self.commands_superseded = 0
        self.commands_dropped = 0
        self._pending_commands = {}             # topic -> value accepted since the last tick
        self._early_commands = []               # accepted before an external clock started
        self._sequence = {}                     # last publication sequence number, by topic
        self._external_now_ns = None            # the latest /clock (use_sim_time)

    def _subscribe(self) -> None:
        command_qos = rclpy_qos_profile(itf.COMMAND_QOS)
        self._commands = {
            topic: self.create_subscription(
                String if topic in itf.MODE_COMMANDS else Float64, topic,
                lambda message, info, t=topic: self._command(t, message, info), command_qos)
            for topic in itf.COMMANDS}
        if self.sim_time:
            self._clock_subscription = self.create_subscription(
                ClockMessage, itf.CLOCK, self._on_clock, rclpy_qos_profile(itf.CLOCK_QOS))
        self._measurements = {
            topic: self.create_subscription(
                JointState, topic, lambda message, t=topic, s=sensor:
                self._on_measurement(s, t, message), rclpy_qos_profile(itf.MEASUREMENT_QOS))
            for topic, sensor in self.measurement_topics.items()}
        settings = self.engine.ensemble.assimilation      # channels read on their own topics
        self._scalar_channels = frozenset(settings.scalar_topics() if settings else ())
        self._measurements.update({
            topic: self.create_subscription(
                Float64, topic, lambda message, t=topic, c=channel:
                self._on_scalar_measurement(c, t, message),
                rclpy_qos_profile(itf.MEASUREMENT_QOS))
            for topic, channel in self.scalar_measurement_topics.items()})

    @property
    def measurement_topics(self) -> dict[str, str]:
        """{topic: sensor} of the rig's sensors the ensemble filter uses (empty: it is off)."""
        settings = self.engine.ensemble.assimilation
        if settings is None or not self.engine.assimilating:
            return {}
        used = [c for c in settings.filter.measurements if c not in settings.scalar_topics()]
        return {getattr(settings.sensors, sensor).topic: sensor
                for sensor, channels in SENSOR_CHANNELS.items()
                if any(c in used for c in channels)}

    @property
    def scalar_measurement_topics(self) -> dict[str, str]:
        """{topic: channel} of the filter's channels that come as std_msgs/Float64 alone."""
        settings = self.engine.ensemble.assimilation
        if settings is None or not self.engine.assimilating:
            return {}
        return {topic: channel for channel, topic in settings.scalar_topics().items()
                if channel in settings.filter.measurements}

    def _received(self, topic: str, message) -> bool:
        """Log a rig message as received; whether the twin's clock runs (else it is refused)."""
        if self.log and self.pacer.started:
            self.log.write(topic, message, self.twin_time_ns())
        if not self.pacer.started:
            self.engine.refuse_measurement(f'{topic}: received before the twin\'s clock '
                                           f'started')
        return self.pacer.started

    def _on_scalar_measurement(self, channel: str, topic: str, message: Float64) -> None:
        """
        Hand a channel's std_msgs/Float64 to the ensemble filter and log it.

        Unstamped: taken as sampled now less its sensor's delay (``delay_s``).
        """
        if not self._received(topic, message):
            return
        value = float(message.data)
        if not math.isfinite(value):
            self.engine.refuse_measurement(f'{topic}: {channel} = {value} is not finite')
            return
        settings = self.engine.ensemble.assimilation
        stamp_s = self.engine.time_s - settings.sensor_of(channel).delay_s
        self.engine.offer_measurement(Sample(SENSOR_OF[channel], stamp_s, {channel: value}))

    def _on_measurement(self, sensor: str, topic: str, message: JointState) -> None:
        """
        Hand a rig sample to the ensemble filter and log it.

        Its stamp: the header's, in the twin's clock (an unset stamp is taken as now); a bad
        sample is refused with a diagnostic.
        """
        if not self._received(topic, message):
            return
        try:
            values = values_from_joint_state(sensor, message.name, message.position,
                                             message.velocity, message.effort)
            values = {c: v for c, v in values.items()               # the others: on their own
                      if c not in self._scalar_channels}
        except ValueError as error:
            self.engine.refuse_measurement(f'{topic}: {error}')
            return
        stamp_ns = message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec
        stamp_s = (stamp_ns - self.epoch_ns) * 1e-9 if stamp_ns else self.engine.time_s
        self.engine.offer_measurement(Sample(sensor, stamp_s, values))

    def _start_line(self) -> str:
        p = self.params
        pace = ('fast, publishing /clock' if self.fast else 'following /clock (use_sim_time)'
                if self.sim_time else f'{p.rate_hz:g} Hz')
        where = (f'logging to {self.log.path}' if self.log else
                 'logging from the first /clock' if p.log_enabled and self.sim_time
                 else 'no log')
        topics = [*self.measurement_topics, *self.scalar_measurement_topics]
        assimilating = (f', assimilating {", ".join(topics)}' if topics else '')
        return (f'drill_twin {__version__}: {self.engine.ensemble.members} ensemble members '
                f'(delta {self.engine.ensemble.dispersion:g}, seed {p.seed}){assimilating}, '
                f'{self.substeps} steps of {self.engine.dt * 1e3:g} ms per tick, {pace}; '
                f'{where}' + ('' if self.tf_enabled else '; no TF (tf2_msgs is not installed)'))

    def _published_topics(self) -> dict:
        """{topic: (message class, QosSpec)} of the node's publishers."""
        return messages.publications(self.stations_m, ensemble=bool(self.engine.ensemble.members),
                                     clock=self.fast, tf=self.tf_enabled,
                                     assimilation=self.engine.assimilating)

    def _open_log(self):
        """
        Open the run's log (a rosbag2 bag in ``log_dir``).

        None if it cannot be created and ``on_log_error`` is continue (LogDirectoryError if
        exit).
        """
        metadata = log_metadata(self.params, self.engine, epoch_ns=self.epoch_ns,
                                substeps=self.substeps, fast=self.fast)
        path = new_log_path(self.params.log_dir)
        try:
            return open_log(path, self.params, self.stations_m, metadata, tf=self.tf_enabled,
                            measurement_topics=self.measurement_topics,
                            scalar_measurement_topics=self.scalar_measurement_topics)
        except OSError as error:
            text = f'cannot write the log {path}: {error.strerror or error}'
            if self.params.on_log_error == 'exit':
                raise LogDirectoryError(text) from None
            self.log_error = text
            self.get_logger().error(text + '; running without a log (on_log_error: continue)')
            return None

    def _on_log_failure(self, now: int) -> None:
        """
        Handle a failed write to the log (disk full, ...).

        The log is closed; say so as an ERROR on /rosout and /diagnostics, then obey
        ``on_log_error`` (exit: stop, status 1).
        """
        error, self.log = self.log.error, None
        stop = self.params.on_log_error == 'exit'
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

    @property
    def config(self):
        """The model configuration the engine was built from."""
        return self.engine.config

    # -- time ----------------------------------------------------------------------------
    @property
    def epoch_ns(self) -> int:
        """
        The twin's clock at step 0 (ns).

        The ROS time at start, 0 when fast, the first /clock with use_sim_time (0 until it
        arrives).
        """
        return self.pacer.epoch_ns or 0

    def twin_time_ns(self) -> int:
        """Return the twin's clock (ns): the epoch plus the simulated time."""
        return self.epoch_ns + self.engine.step_index * self.dt_ns

    def _clock_now_ns(self) -> int | None:
        """Return the clock the twin follows (ns): ROS clock, latest /clock, None when fast."""
        if self.fast:
            return None
        if self.sim_time:
            return self._external_now_ns
        return self.get_clock().now().nanoseconds

    def _on_clock(self, message: ClockMessage) -> None:
        self._external_now_ns = message.clock.sec * 1_000_000_000 + message.clock.nanosec
        if not self.pacer.started:
            self.pacer.start(self._external_now_ns)
            self._on_clock_started()

    def _on_clock_started(self) -> None:
        """
        Start the twin's clock at the first /clock (use_sim_time).

        Open the log, record the commands that came before (they act from step 0), publish the
        static frames.
        """
        if self.params.log_enabled:
            self.log = self._open_log()
        for topic, message in self._early_commands:
            if self.log:
                self.log.write(topic, message, self.epoch_ns)
        self._early_commands.clear()
        self._report('info', f'/clock started at {self.epoch_ns * 1e-9:.3f} s: the twin '
                     f'follows it' + (f'; logging to {self.log.path}' if self.log else ''))
        self._publish_static_tf()

    def _publish_static_tf(self) -> None:
        if self.tf_enabled:
            now = self.twin_time_ns()
            self._publish(itf.TF_STATIC, messages.tf(messages.static_transforms(
                self.stations_m, now)), now)

    # -- commands ------------------------------------------------------------------------
    def _command(self, topic, message, info) -> None:
        """Apply a command (it takes effect on the next model step), log it, echo it then."""
        self._count_dropped(topic, info)
        apply = getattr(self.engine, _ENGINE_COMMANDS[topic])
        try:
            apply(message.data)                     # counts it (received, rejected)
        except CommandRejected as error:
            self._report('warn', f'{topic}: {error}; the previous command stays')
            return
        if topic in self._pending_commands:         # the previous one never took effect
            self.commands_superseded += 1
        self._pending_commands[topic] = message.data
        if not self.pacer.started:
            self._early_commands.append((topic, message))
        elif self.log:
            self.log.write(topic, message, self.twin_time_ns())    # takes effect at this time
        if self.live_view and topic in _LIVE_VIEW_KEYS:
            self.live_view.command(self.engine.time_s, **{_LIVE_VIEW_KEYS[topic]: message.data})

    def _count_dropped(self, topic: str, info) -> None:
        """
        Commands lost on the way.

        Gaps in the publisher's sequence numbers (counted while one publisher sends the topic:
        the numbers of several publishers interleave).
        """
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
        steps = self.pacer.steps(self._clock_now_ns(), self.engine.step_index)
        effect_ns = self.twin_time_ns()     # the start of the first step the commands act in
        applied = dict(self._pending_commands)
        snapshot = self._advance(steps) if steps else None
        if snapshot is None:                # not due yet, or the model stalled (reported)
            return
        now = self.twin_time_ns()
        log_states = self._log_states_due(now)
        for topic, value in applied.items():
            self._publish(itf.cmd_applied_topic(topic),
                          messages.command_applied(topic, value, effect_ns), now)
        logging = self._logging()

        def wanted(topic):
            return logging and messages.logged(topic, log_states) or self._heard(topic)

        for topic, message in messages.tick_messages(snapshot, self.stations_m, now,
                                                     self._plan(snapshot), wanted):
            self._publish(topic, message, now, log=messages.logged(topic, log_states))
        self._after_tick(snapshot, now)

    def _log_states_due(self, now_ns: int) -> bool:
        """Whether this tick's states go to the log (at most ``log_state_rate_hz``)."""
        period = round(1e9 / self.params.log_state_rate_hz)
        if self._next_state_log_ns is None:         # on the grid of the period's multiples
            self._next_state_log_ns = -(-now_ns // period) * period
        if now_ns < self._next_state_log_ns:
            return False
        self._next_state_log_ns = (now_ns // period + 1) * period
        return True

    def _advance(self, steps: int):
        """Step the engine; the snapshot, or None if the model stalled (then stopping)."""
        if self.ticks == 0:                 # the real-time factor counts from the first tick
            self._health_mark = (time.perf_counter(), self.engine.time_s)
        try:
            snapshot = self.engine.advance(steps)
        except TwinStalled as error:
            self._stalled(error)
            return None
        self.ticks += 1
        if self.live_view:
            self.live_view.update(snapshot)
        if self.status:
            self.status.update(snapshot)
        self._advanced_at = time.monotonic()
        self._pending_commands.clear()
        self._latest_health = snapshot.health
        self.monitor.observe_events(snapshot.events)
        return snapshot

    def _plan(self, snapshot) -> messages.TickPlan:
        """
        Plan what this tick publishes besides the states.

        Rates: ``kpi_rate_hz`` for the KPIs and /tf, ``ensemble_rate_hz`` for the ensemble.
        """
        kpis = self._due(self.params.kpi_rate_hz)
        ensemble = snapshot.ensemble_mean is not None and self._due(self.params.ensemble_rate_hz)
        return messages.TickPlan(
            kpis=kpis, clock=self.fast, tf=self.tf_enabled and kpis,
            ensemble_stamp_ns=(self.epoch_ns + snapshot.ensemble_step * self.dt_ns
                               if ensemble else None))           # a tick behind

    def _after_tick(self, snapshot, now: int) -> None:
        """Report the tick's events, notice a failed log, stop at ``duration_s``."""
        for event in snapshot.events:
            if event.kind in QUIET_EVENTS:
                # A whirling string hits the wall tens of times a second: every event goes to
                # /diagnostics and the log's /rosout, the console gets a count a health period.
                self._report(event.level, event.message, console=False)
                self._impacts_unreported += event.kind == 'impact'
                self._refused_unreported += event.kind == 'measurement_rejected'
            elif event.kind != 'command_rejected':              # already reported
                self._report(event.level, event.message)
        for record in snapshot.analyses:
            self._innovations.append((record.nis, record.measurements))
        if snapshot.analyses:                       # the latest analysis's parameters
            latest = snapshot.analyses[-1]
            for topic, message in (messages.germ_messages(latest)
                                   + messages.law_messages(latest)
                                   + messages.bias_messages(latest)):
                self._publish(topic, message, now)
        if self.log and not self.log.open:          # a write failed (disk full, ...)
            self._on_log_failure(now)
            if self.done.done():                    # on_log_error: exit
                return
        duration = self.params.duration_s
        if duration > 0 and self.engine.time_s >= duration - 0.5 * self.engine.dt:
            self._report('info', f'{duration:g} s simulated: stopping')
            self._publish_health()                  # the last period's report
            self.done.set_result(True)

    def _stalled(self, error: TwinStalled) -> None:
        """Report that the model cannot go on (rosout, an ERROR health status) and stop."""
        self.monitor.note('error', 'stalled', str(error))
        self._report('error', f'{error}; stopping')
        self._publish_health()
        self.failed = True
        self.done.set_result(False)

    def _steps_behind_wall_clock(self) -> int:
        """
        Return the whole model steps the twin is behind the clock it follows.

        That clock is the ROS clock, or /clock with use_sim_time, counted since the first
        tick; 0 when fast.
        """
        return self.pacer.behind(self._clock_now_ns(), self.engine.step_index)

    def _due(self, rate_hz: float) -> bool:
        every = max(1, round(1.0 / (rate_hz * self.tick_s)))
        return self.ticks % every == 0

    def _publish(self, topic: str, message, time_ns: int, log: bool = True) -> None:
        """
        Send ``message`` to the subscribers of ``topic`` and, if ``log``, to the log.

        Only where it goes somewhere: a volatile topic with no matched subscription is not
        published (the middleware would drop the message: a subscriber hears a topic from its
        matching on, published or not), a durable one always is (kept for late joiners).
        """
        log = log and self._logging()
        heard = self._heard(topic)
        if not (heard or log):
            return
        data = serialize_message(message)           # once, for the wire and for the log
        if heard:
            try:
                self._outputs[topic].publish(data)
            except RCLError:
                if self.context.ok():
                    raise
                return                              # a signal shut the context down mid-tick
        if log:
            self.log.write_serialized(topic, data, time_ns)

    def _heard(self, topic: str) -> bool:
        """Whether a message on ``topic`` reaches a subscriber (matched, or a late joiner)."""
        if topic in self._durable:
            return True
        try:
            return self._outputs[topic].get_subscription_count() > 0
        except RCLError:
            if self.context.ok():
                raise
            return False                            # a signal shut the context down mid-tick

    def _logging(self) -> bool:
        """Whether the log takes messages (open, not failed)."""
        return self.log is not None and self.log.open

    # -- health --------------------------------------------------------------------------
    def _on_health(self) -> None:
        if self.done.done() or not self.context.ok():
            return
        self._publish_health()

    def _publish_health(self) -> None:
        """Publish the health report of the period since the last one on /diagnostics."""
        impacts, self._impacts_unreported = self._impacts_unreported, 0
        if impacts:
            self.get_logger().warning(
                f'{impacts} borehole impact{"s" if impacts > 1 else ""} since the last health '
                f'report (each one on {itf.DIAGNOSTICS} and in the log)')
        refused, self._refused_unreported = self._refused_unreported, 0
        if refused:
            self.get_logger().warning(
                f'{refused} measurement sample{"s" if refused > 1 else ""} refused since the '
                f'last health report (each one, with why, on {itf.DIAGNOSTICS} and in the log)')
        values = self._health_values()
        counters = dict(self._latest_health, commands_dropped=self.commands_dropped)
        report = self.monitor.report(counters, values)
        now = self.twin_time_ns()
        self._publish(itf.DIAGNOSTICS, messages.health_report(report, now), now)
        if self.log:
            self.log.flush()

    def _health_values(self) -> dict:
        """Return the figures of a health report; note lag and a missing log in the monitor."""
        wall, simulated = time.perf_counter(), self.engine.time_s
        previous_wall, previous_simulated = self._health_mark
        self._health_mark = (wall, simulated)
        factor = (simulated - previous_simulated) / max(wall - previous_wall, 1e-9)
        h = self._latest_health
        lag_s = self._steps_behind_wall_clock() * self.engine.dt
        self._note_clock(factor, lag_s)
        logging = bool(self.log and self.log.open)
        if self.params.log_enabled and not logging and self.pacer.started:
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
        if self.measurement_topics or self.scalar_measurement_topics:
            values.update(self._assimilation_values(h))
        return values

    def _assimilation_values(self, h: dict) -> dict:
        """Return the filter's figures of the period; note missing samples, large NIS."""
        innovations, self._innovations = self._innovations, []
        received = self.engine.measurements_received
        new, self._measurements_at_report = (received - self._measurements_at_report,
                                             received)
        values = {'assimilation_analyses': len(innovations),
                  'measurements_received': received,
                  'measurements_used': h.get('measurements_used', 0),
                  'measurements_refused': h.get('measurements_refused', 0)}
        if innovations:
            nis = sum(n for n, _ in innovations) / max(sum(m for _, m in innovations), 1)
            values['nis_per_measurement'] = f'{nis:.3f}'
            if nis > NIS_WARN_PER_MEASUREMENT:
                self.monitor.note('warn', 'innovations', f'the rig\'s measurements disagree '
                                  f'with the ensemble: normalised innovation squared {nis:.3g} '
                                  f'per measured value (expected 1; the noise levels or the '
                                  f'model are off)')
        else:
            values['nis_per_measurement'] = 'none'
        if self.ticks and not new:
            self.monitor.note('warn', 'measurements', 'no measurement sample arrived on '
                              + ', '.join([*self.measurement_topics,
                                           *self.scalar_measurement_topics])
                              + ' in the period: the '
                              'ensemble runs in open loop')
        return values

    def _note_clock(self, factor: float, lag_s: float) -> None:
        """
        Note lag behind the clock the twin follows, and a frozen or missing clock.

        Also a /clock that went back (use_sim_time).
        """
        if self.sim_time and not self.pacer.started:
            self.monitor.note('warn', 'clock', 'waiting for the first /clock message '
                              '(use_sim_time)')
        elif self.sim_time and lag_s < 0:
            self.monitor.note('warn', 'clock', f'/clock went back {-lag_s:.3f} s behind the '
                              f'twin; it waits for /clock to reach it again')
        late = lag_s > 0.1 or (factor < 0.95 and not self.sim_time)
        if not self.fast and self.ticks and late:
            what, clock = (('/clock', '/clock') if self.sim_time
                           else ('real time', 'the wall clock'))
            self.monitor.note('warn', 'lag', f'falling behind {what} ({1e3 * lag_s:.0f} ms '
                              f'behind {clock}, real-time factor {factor:.3f})')
        still = time.monotonic() - self._advanced_at
        if self.ticks and still > FROZEN_AFTER_S:
            self.monitor.note('warn', 'frozen', f'the twin\'s clock has not advanced for '
                              f'{still:.1f} s')

    def _report(self, level: str, text: str, console: bool = True) -> None:
        """Write a log line to rosout (unless not ``console``), and to the MCAP log's /rosout."""
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
                    f'{parameter.name} must be one of {spec.choices_text()}'))
        updated = self.params.with_values(**{p.name: p.value for p in parameters
                                             if p.name in BY_NAME})
        if updated.hook_load_min_n > updated.hook_load_max_n:
            return SetParametersResult(successful=False,
                                       reason='hook_load_min_n must not exceed hook_load_max_n')
        if updated.health_rate_hz != self.params.health_rate_hz:
            self.health_timer.timer_period_ns = int(round(1e9 / updated.health_rate_hz))
        if (updated.top_drive_controller
                and updated.top_drive_controller != self.params.top_drive_controller):
            self.engine.set_top_drive_controller(updated.top_drive_controller)
        self.params = updated
        self.engine.limits = command_limits(updated)
        self.engine.kpi_window_s = float(updated.kpi_window_s)
        return SetParametersResult(successful=True)

    # -- ending --------------------------------------------------------------------------
    def close(self) -> None:
        """Stop the ensemble worker and complete the log (safe to call twice)."""
        self.engine.close()
        if self.log:
            self.log.close()
            if self.log.error:                      # completing the log failed (disk full)
                self.get_logger().error(self.log.error)


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


def _run(ros_args: list[str], view: str | None = None, console: bool = False) -> int:
    from rclpy.exceptions import NotInitializedException, ParameterException

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
        try:
            params = TwinParameters.from_values(validate_ros_arguments(ros_args))
        except ParameterError as error:
            print(f'drill-twin: parameter: {error}', file=sys.stderr)
            return 2
        executor = SingleThreadedExecutor()
        node = create_twin_node(params)
        if view:
            from drill_twin.viz.live_view import LiveView
            settings = node.engine.ensemble.assimilation
            node.live_view = LiveView(node.stations_m, node.config,
                                      assimilation=node.engine.assimilating,
                                      law=settings is not None
                                      and settings.filter.parameters == 'law',
                                      bias_channels=() if settings is None
                                      else settings.estimated_bias_channels())
            node.live_view.spawn_viewer(web=(view == 'web'))
        if console:
            from drill_twin.viz.console import StatusPrinter
            node.status = StatusPrinter(sys.stderr)
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
            _let_the_signal_handler_finish()
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


def _let_the_signal_handler_finish(timeout_s: float = 1.0) -> None:
    """
    Wait until rclpy's signal handler has shut the context down (at most ``timeout_s``).

    On SIGINT or SIGTERM rclpy shuts the context down on its own thread while Python raises
    KeyboardInterrupt here at once; shutting the context down again at the same time corrupted
    the heap or raised "rcl_shutdown already called" (3 runs in 60 of a signal during start-up,
    test_signal_while_starting).
    """
    deadline = time.monotonic() + timeout_s
    while rclpy.ok() and time.monotonic() < deadline:
        time.sleep(0.005)
