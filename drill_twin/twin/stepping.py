"""Stepping a batch that may diverge: restart the failed members from a safe state, retry.

The twin must never stop its clock or publish a failed step. :class:`GuardedSimulator` wraps
a :class:`~drill_twin.dynamics.simulator.Simulator`: a step that diverges has its failed
members restarted from a safe state (their depth kept) and is retried once; if that fails
too the step is skipped, and after MAX_CONSECUTIVE_FAILURES skipped steps in a row it raises
TwinStalled. Every restart becomes a :class:`TwinEvent`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from drill_twin.dynamics.simulator import SimulationDiverged, Simulator


class TwinStalled(RuntimeError):
    """The model failed MAX_CONSECUTIVE_FAILURES steps in a row, even from a safe state: the
    configuration cannot be integrated (the clock would otherwise stand still)."""


MAX_CONSECUTIVE_FAILURES = 100
"""Steps in a row that may fail (each retried once from a safe state) before TwinStalled."""


@dataclass(frozen=True)
class TwinEvent:
    """Something the rig should hear about.

    kind: 'impact' (a node touches the wall), 'contact_end', 'lift_off', 'landing',
    'diverged' (a member was reset), 'command_rejected', 'ensemble_failed'. level: 'info',
    'warn' or 'error'.
    """

    kind: str
    level: str
    time_s: float
    message: str
    values: dict = field(default_factory=dict)


class GuardedSimulator:
    """A simulator whose failed steps restart the failed members and are retried once.

    Args:
        simulator: the batch.
        first_member: the number of its member 0 in event messages (the mean model is 0,
            the ensemble members 1..N).
        name: what the batch is called in messages when it holds one member
            ('the mean model') or when any member fails ('ensemble members').
    """

    def __init__(self, simulator: Simulator, first_member: int, name: str):
        self.simulator = simulator
        self.first_member = first_member
        self.name = name
        self.events: list[TwinEvent] = []
        self.resets = 0
        self._consecutive_failures = 0

    def step(self):
        """One step; the StepResult, or None if the step failed even after a restart."""
        for _ in range(2):
            try:
                result = self.simulator.step()
                self._consecutive_failures = 0
                return result
            except SimulationDiverged as error:
                self._recover(error)
        self._consecutive_failures += 1
        if self._consecutive_failures >= MAX_CONSECUTIVE_FAILURES:
            raise TwinStalled(f'{MAX_CONSECUTIVE_FAILURES} steps in a row failed, even from a '
                              f'safe state, at t = {self.simulator.time_s:.6g} s: the model '
                              f'cannot be integrated with this configuration')
        return None

    def _recover(self, error: SimulationDiverged) -> None:
        members = list(error.members) or list(range(self.simulator.members))
        self.simulator.reset_members(members)
        self.resets += len(members)
        numbers = [self.first_member + m for m in members]
        which = (self.name if self.simulator.members == 1
                 else f'{self.name} {numbers}')
        self.events.append(TwinEvent(
            'diverged', 'error', self.simulator.time_s,
            f'{which} diverged ({error}); restarted from a safe state at the same depth',
            {'members': ' '.join(map(str, numbers)), 'time_s': f'{error.time_s:.6g}'}))

    def take_events(self) -> list[TwinEvent]:
        events, self.events = self.events, []
        return events
