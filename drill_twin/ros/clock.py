"""
The twin node's clock: its pace, its epoch, and what falls due at a tick.

A :class:`TwinClock` holds the :class:`~drill_twin.ros.pacing.Pacer` of the node's pace, the
clock it follows (the ROS clock, or the latest external /clock with ``use_sim_time``, or none
when fast) and the ticks taken; the twin's clock is the epoch plus the engine's steps. It says
how many model steps a tick takes, how far the twin is behind, and which rate-limited
publications (KPIs, ensemble, TF, the log's every-tick states) are due.

Times are integer nanoseconds. No node is needed: it works (and is tested) without
``rclpy.init``.
"""
from __future__ import annotations

from collections.abc import Callable

from drill_twin.ros import messages
from drill_twin.ros.pacing import Pacer


class TwinClock:
    """
    The node's clock and tick schedule (see the module docstring).

    :param pace: 'fast', 'wall' or 'external' (use_sim_time).
    :param dt_s: model time step (s).
    :param rate_hz: tick rate of the node's timer (Hz).
    :param step_index: the engine's steps taken so far (a call).
    :param wall_now_ns: the ROS clock (ns; a call). In wall pace it is read once here: the
        twin's clock starts at the ROS time the clock is made.
    """

    def __init__(self, pace: str, dt_s: float, rate_hz: float,
                 step_index: Callable[[], int], wall_now_ns: Callable[[], int]):
        self.substeps = max(1, round(1.0 / (rate_hz * dt_s)))
        """Model steps of one tick."""
        self.tick_s = self.substeps * dt_s
        """Simulated time of one tick (s)."""
        self.dt_ns = int(round(dt_s * 1e9))
        self.ticks = 0
        """Ticks that took steps."""
        self.external_now_ns: int | None = None
        """The latest external /clock (use_sim_time), None before the first."""
        self._step_index = step_index
        self._wall_now_ns = wall_now_ns
        self._next_state_log_ns: int | None = None
        self.pacer = Pacer(pace, self.dt_ns, self.substeps,
                           None if pace == 'external' else 0 if pace == 'fast'
                           else wall_now_ns())

    @property
    def fast(self) -> bool:
        """Whether the twin runs as fast as it can (and publishes /clock)."""
        return self.pacer.pace == 'fast'

    @property
    def started(self) -> bool:
        """False while an external clock has not sent its first message."""
        return self.pacer.started

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
        return self.epoch_ns + self._step_index() * self.dt_ns

    def followed_ns(self) -> int | None:
        """Return the clock the twin follows (ns): ROS clock, latest /clock, None when fast."""
        if self.pacer.pace == 'fast':
            return None
        if self.pacer.pace == 'external':
            return self.external_now_ns
        return self._wall_now_ns()

    def external(self, time_ns: int) -> bool:
        """Take an external /clock time (ns); whether it is the first (the clock starts)."""
        self.external_now_ns = time_ns
        if self.pacer.started:
            return False
        self.pacer.start(time_ns)
        return True

    def steps_due(self) -> int:
        """Return the model steps this tick takes."""
        return self.pacer.steps(self.followed_ns(), self._step_index())

    def steps_behind(self) -> int:
        """
        Return the whole model steps the twin is behind the clock it follows.

        That clock is the ROS clock, or /clock with use_sim_time, counted since the first
        tick; 0 when fast; negative if an external clock went back.
        """
        return self.pacer.behind(self.followed_ns(), self._step_index())

    def due(self, rate_hz: float) -> bool:
        """Whether this tick is one of those of a publication at ``rate_hz`` (of twin time)."""
        every = max(1, round(1.0 / (rate_hz * self.tick_s)))
        return self.ticks % every == 0

    def states_due(self, now_ns: int, rate_hz: float) -> bool:
        """
        Whether this tick's every-tick states go to the log (at most ``rate_hz``).

        The first tick at or after each multiple of the period, on the twin's clock.
        """
        period = round(1e9 / rate_hz)
        if self._next_state_log_ns is None:         # on the grid of the period's multiples
            self._next_state_log_ns = -(-now_ns // period) * period
        if now_ns < self._next_state_log_ns:
            return False
        self._next_state_log_ns = (now_ns // period + 1) * period
        return True

    def plan(self, snapshot, *, kpi_rate_hz: float, ensemble_rate_hz: float,
             tf: bool) -> messages.TickPlan:
        """
        Plan what this tick publishes besides the states.

        Rates: ``kpi_rate_hz`` for the KPIs and /tf (if ``tf``), ``ensemble_rate_hz`` for the
        ensemble, stamped with its own time (a tick behind); /clock when fast.
        """
        kpis = self.due(kpi_rate_hz)
        ensemble = snapshot.ensemble_mean is not None and self.due(ensemble_rate_hz)
        return messages.TickPlan(
            kpis=kpis, clock=self.fast, tf=tf and kpis,
            ensemble_stamp_ns=(self.epoch_ns + snapshot.ensemble_step * self.dt_ns
                               if ensemble else None))
