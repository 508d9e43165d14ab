"""
The hole's rate as the filter sees it: the block's slope against each member's own drilling.

Over a window, the block's least-squares slope is compared with what each member's own law
drilled over the same window. Why: at every analysis the block position moves the members'
bits, and a member on bottom keeps its bit on bottom, so the analysis itself drills the part
of the hole a member's law does not; the law's parameters then receive a weak share of the
block's evidence (docs/ASSIMILATION.md). This observation gives them the rest. Over
consecutive windows of ``window_s`` the rig's block samples give a least-squares slope
(m/s); each member's prediction is the least-squares slope, over the steps of the same
window, of its *own block trajectory*

    own(t) = block(t) - hole(t) + D(t),

the string's stretch above its hole bottom plus D, the depth its law drilled during steps
(the hole's advance over each step; a jump of the hole between steps, by an analysis or a
copy, is not drilling). Over a window at one set-point the stretch's change is small against
the drilled depth, and it is in the truth's block as well.

The window's sums (sum of own, sum of t own) and D are linear in the members, so every
analysis applies its transform to them as to the state (an ensemble smoother step, as
:class:`.sequential.SequentialFilter` does with its stored predictions): the own trajectory
stays continuous through an analysis except for what the analysis does not do linearly (the
hole following an on-bottom bit). The observation's variance is that of a least-squares
slope under white noise of the block's standard deviation, sigma^2 / sum (s - mean s)^2.

With ``steady_law`` the prediction is instead each member's *law's* steady ROP at its mean
bit speed and WOB over the window (:func:`.steady_law.steady_point`, with its germ and its
factors of a1 ... a5; 0 where the law cannot drill there): what a string drilling steadily at
those means drills. It hands the block's slope to the law's parameters directly, where the
own drilling hands it to whatever the member's dynamics do with its law (an oscillating
member drills faster than its law's steady point: the ROP is cut at 0). It is exact for a
truth at its steady point and biased by the truth's own oscillation otherwise. The window's
sums of bit speed and WOB are what each member went through and take no transform; its law is
taken as it is when the window is analysed.

A window is analysed at the first analysis after its end plus the hook sensor's delay; it
needs block samples over at least half of it (else it is skipped). A member restarted by the
state guard keeps its hole but not its stretch: its own trajectory jumps there (rare; the
window's slope carries it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drill_twin.assimilation.steady_law import steady_point

MINIMUM_COVERAGE = 0.5
"""A window is used when its block samples span at least this fraction of it."""


@dataclass(eq=False)
class _Window:
    """One window's sums: over steps (members') and over block samples (the rig's)."""

    start_s: float
    end_s: float
    members: int
    steps: int = 0
    sum_t: float = 0.0
    sum_tt: float = 0.0
    sum_own: np.ndarray = None
    sum_t_own: np.ndarray = None
    sum_speed: np.ndarray = None
    sum_weight: np.ndarray = None

    def __post_init__(self):
        self.sum_own = np.zeros(self.members)
        self.sum_t_own = np.zeros(self.members)
        self.sum_speed = np.zeros(self.members)
        self.sum_weight = np.zeros(self.members)

    def add_step(self, time_s: float, own: np.ndarray, speed: np.ndarray,
                 weight: np.ndarray) -> None:
        t = time_s - self.start_s
        self.steps += 1
        self.sum_t += t
        self.sum_tt += t * t
        self.sum_own += own
        self.sum_t_own += t * own
        self.sum_speed += speed
        self.sum_weight += weight

    def member_slopes(self) -> np.ndarray | None:
        """Least-squares slope of each member's own trajectory over the steps (m/s)."""
        n = self.steps
        spread = n * self.sum_tt - self.sum_t ** 2
        if n < 2 or spread <= 0:
            return None
        return (n * self.sum_t_own - self.sum_t * self.sum_own) / spread


@dataclass(frozen=True)
class HoleRateObservation:
    """One window's observation: the members' slopes (N,), the block's slope and variance."""

    start_s: float
    end_s: float
    predicted: np.ndarray
    observed_m_per_s: float
    variance: float
    samples: int


class HoleRateWindows:
    """
    The windows of one filter over members 0..members-1 of ``simulator`` (module docstring).

    :param window_s: the windows' length (s); they follow each other from ``start_s``.
    :param delay_s: how long after a window's end its last block samples may arrive (s).
    :param steady_law: predict each member's law's steady ROP at its window's mean bit speed
        and WOB, not its own drilling (module docstring).
    """

    def __init__(self, simulator, members: int, window_s: float, start_s: float,
                 delay_s: float = 0.0, steady_law: bool = False):
        self.simulator = simulator
        self.steady_law = bool(steady_law)
        self.members = int(members)
        self.window_s = float(window_s)
        self.delay_s = float(delay_s)
        self.drilled = np.zeros(self.members)
        """D: the depth each member's law drilled during steps since the start (m)."""
        self._hole_seen = self._hole()
        self._open = _Window(start_s, start_s + self.window_s, self.members)
        self._closed: list[_Window] = []
        self._samples: list[tuple[float, float]] = []
        self._analysed_until_s = -math.inf

    def _hole(self) -> np.ndarray:
        return np.array(self.simulator.hole_u()[:self.members], dtype=float)

    def own(self, block: np.ndarray) -> np.ndarray:
        """Return the members' own block trajectory at this instant (m), given their block."""
        return block - self._hole_seen + self.drilled

    def after_step(self, time_s: float, block: np.ndarray, speed: np.ndarray,
                   weight: np.ndarray) -> None:
        """
        Count the step's drilling and add the own trajectory.

        ``block``: the members' block positions (N,), m; ``speed``: their bit speeds (N,),
        rad/s; ``weight``: their WOB (N,), N (> 0 in compression).
        """
        hole = self._hole()
        self.drilled += hole - self._hole_seen
        self._hole_seen = hole
        while time_s > self._open.end_s + 1e-9:
            self._closed.append(self._open)
            self._open = _Window(self._open.end_s, self._open.end_s + self.window_s,
                                 self.members)
        self._open.add_step(time_s, self.own(block), speed, weight)

    def offer(self, stamp_s: float, block_m: float) -> None:
        """Take a block sample (one stamped in a window already analysed is dropped)."""
        if stamp_s > self._analysed_until_s + 1e-9:
            self._samples.append((float(stamp_s), float(block_m)))

    def transform(self, matrix: np.ndarray) -> None:
        """Apply an analysis's member transform ``matrix`` (N, N) to the sums and to D."""
        self.drilled = matrix @ self.drilled
        for window in (*self._closed, self._open):
            window.sum_own = matrix @ window.sum_own
            window.sum_t_own = matrix @ window.sum_t_own

    def after_write(self) -> None:
        """Take the holes as they are after a write (an analysis's jump is not drilling)."""
        self._hole_seen = self._hole()

    def copy(self, targets, sources) -> None:
        """Members ``targets`` became copies of ``sources``: so do their histories."""
        targets, sources = np.asarray(targets, int), np.asarray(sources, int)
        self.drilled[targets] = self.drilled[sources]
        self._hole_seen[targets] = self._hole_seen[sources]
        for window in (*self._closed, self._open):
            window.sum_own[targets] = window.sum_own[sources]
            window.sum_t_own[targets] = window.sum_t_own[sources]
            window.sum_speed[targets] = window.sum_speed[sources]
            window.sum_weight[targets] = window.sum_weight[sources]

    def steady_rates(self, window: _Window) -> np.ndarray:
        """
        Return each member's law's steady ROP at its mean bit speed and WOB over ``window``.

        (N,), m/s; 0 where the member's law (its factors of a1 ... a5 and germ as they are
        now) cannot drill at those means, or its bit did not press the rock on average.
        """
        integrator = self.simulator.integrator
        scales, germs = integrator.law_scales, integrator.germ
        law = self.simulator.law
        speed = window.sum_speed / window.steps
        weight = window.sum_weight / window.steps
        rates = np.zeros(self.members)
        for i in range(self.members):
            if not (speed[i] > 0 and weight[i] > 0):
                continue
            member_law = law if scales is None else law.scaled(scales[i])
            rop, _ = steady_point(member_law, float(speed[i]), float(weight[i]),
                                  None if germs is None else germs[i])
            rates[i] = rop if math.isfinite(rop) else 0.0
        return rates

    def due(self, now_s: float, noise_std) -> list[HoleRateObservation]:
        """
        Return the observations of the windows whose samples are all in by ``now_s``.

        ``noise_std(value)``: the block's noise standard deviation (m). A window with block
        samples over less than :data:`MINIMUM_COVERAGE` of it is dropped.
        """
        ready = [w for w in self._closed if now_s >= w.end_s + self.delay_s - 1e-9]
        self._closed = [w for w in self._closed if now_s < w.end_s + self.delay_s - 1e-9]
        observations = []
        for window in ready:
            inside = np.array([(s, v) for s, v in self._samples
                               if window.start_s < s <= window.end_s + 1e-9]).reshape(-1, 2)
            stamps, values = inside[:, 0], inside[:, 1]
            predicted = (self.steady_rates(window) if self.steady_law and window.steps
                         else window.member_slopes())
            if (predicted is None or stamps.size < 3
                    or np.ptp(stamps) < MINIMUM_COVERAGE * self.window_s):
                continue
            centred = stamps - stamps.mean()
            weights = centred / (centred @ centred)
            sigma = float(noise_std(values.mean()))
            observations.append(HoleRateObservation(
                start_s=window.start_s, end_s=window.end_s, predicted=predicted,
                observed_m_per_s=float(weights @ values),
                variance=sigma * sigma / float(centred @ centred), samples=stamps.size))
        if ready:
            self._analysed_until_s = max(w.end_s for w in ready)
            self._samples = [(s, v) for s, v in self._samples
                             if s > self._analysed_until_s + 1e-9]
        return observations
