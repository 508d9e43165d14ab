"""
What the Newmark integrator steps and what a step reports: a batch's state, a step's result.

:class:`BatchState` is the state of m members at one time; :class:`StepResult` the outcome of
one step (success, per-member flags, the forces of the final state); :class:`Counters` the
work done so far. A step makes its result with :func:`make_step_result`, at the time loop's
rate (:func:`drill_twin.numerics.records.record`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from drill_twin.model.forces import ForceEvaluation
from drill_twin.numerics.records import record


@dataclass
class BatchState:
    """
    The state of m members at time ``time_s``.

    q, q_rate, q_acceleration: reduced coordinates and derivatives, shape (m, n).
    top_angle_rad, top_speed_rad_per_s, top_acceleration_rad_per_s2: the driven rotation
    (shared by all members); hook_load_n: the hook load in force (N), one for the batch or one
    per member, (m,) (an ensemble whose lines follow the rig's block). hole_u: the hole bottom as
    an axial displacement of the bit from the prestressed state, (m,) (m, down): the deepest
    the bit has been; the bit is off bottom when its displacement is smaller. None: the bit
    is on bottom (the hole bottom is where the bit is).
    """

    time_s: float
    q: np.ndarray
    q_rate: np.ndarray
    q_acceleration: np.ndarray
    top_angle_rad: float
    top_speed_rad_per_s: float
    top_acceleration_rad_per_s2: float
    hook_load_n: float | np.ndarray
    hole_u: np.ndarray | None = None

    def copy(self) -> 'BatchState':
        """Return a copy whose arrays are the copy's own."""
        return self._with(slice(None))

    def take(self, members) -> 'BatchState':
        """Return the state of ``members`` (indices) only, copied."""
        return self._with(members)

    def _with(self, members) -> 'BatchState':
        hook = self.hook_load_n
        return BatchState(
            time_s=self.time_s, q=self.q[members].copy(), q_rate=self.q_rate[members].copy(),
            q_acceleration=self.q_acceleration[members].copy(),
            top_angle_rad=self.top_angle_rad, top_speed_rad_per_s=self.top_speed_rad_per_s,
            top_acceleration_rad_per_s2=self.top_acceleration_rad_per_s2,
            hook_load_n=np.asarray(hook)[members].copy() if np.ndim(hook) else hook,
            hole_u=None if self.hole_u is None else self.hole_u[members].copy())


@dataclass(frozen=True)
class StepResult:
    """
    Outcome of one step: success unless a member diverged or did not converge.

    converged, finite: per member (m,); iterations: used; error: final relative velocity
    increment per member; message: why it failed ('' on success); forces: the forces of the
    final state (the bit's exactly, the others at each member's last evaluation).
    retries: (m,) sub-steps each member was integrated on after its full step failed (0 when
    the full step worked; set by the Simulator, None from the integrator alone). on_bottom: (m,)
    the bit on the rock at the step's end (within ON_BOTTOM_TOLERANCE_M of the surface under
    it), as the step's kernel found it; None where a state was merged from other steps (the
    Simulator then tests its state). members_on_bottom, members_lifted: how many of on_bottom
    and of the final evaluation's lift-off flags are set, counted by the kernel (so that the
    time loop's checks need no pass of their own over the flags); None like on_bottom.
    """

    success: bool
    converged: np.ndarray
    finite: np.ndarray
    iterations: int
    error: np.ndarray
    message: str
    forces: ForceEvaluation
    retries: np.ndarray | None = None
    on_bottom: np.ndarray | None = None
    members_on_bottom: int | None = None
    members_lifted: int | None = None


def make_step_result(success, converged, finite, iterations, error, message, forces, retries,
                     on_bottom, members_on_bottom, members_lifted) -> StepResult:
    """Return StepResult(...) of every field, at the time loop's rate (:func:`record`)."""
    return record(StepResult, success=success, converged=converged, finite=finite,
                  iterations=iterations, error=error, message=message, forces=forces,
                  retries=retries, on_bottom=on_bottom, members_on_bottom=members_on_bottom,
                  members_lifted=members_lifted)


def merged_result(result: StepResult, **changes) -> StepResult:
    """
    Return ``result`` with ``changes``, for a state merged from other steps.

    What the step's kernel found of its own output (on_bottom and the counts beside it) no
    longer holds: None.
    """
    return replace(result, on_bottom=None, members_on_bottom=None, members_lifted=None,
                   **changes)


@dataclass
class Counters:
    """Work done so far."""

    steps: int = 0
    iterations: int = 0
    force_evaluations: int = 0
    bit_law_evaluations: int = 0
    failed_steps: int = 0
