"""
Stepping a batch that may diverge or break physics: restart the failed members, go on.

The twin must never stop its clock or publish a failed or implausible step.
:class:`GuardedSimulator` steps a :class:`~drill_twin.integrator.simulator.Simulator` through
what drives it (a rig, :class:`~drill_twin.rig.rig.Rig`: anything with ``simulator``, ``step()``
that puts itself back when the simulator refuses the step, and ``reset_members(members)``):

- a step that diverges has its failed members restarted from a safe state (their depth
  kept) and is retried once; if that fails too the step is skipped;
- a step that converges is checked by the :class:`~drill_twin.integrator.guard.StateGuard`: a
  member that breaks a physical bound is put back to its state before the step (the last
  good one) and restarted from a safe state at that depth; if even the safe state breaks a
  bound (a configuration that cannot represent the operating point) it keeps its last good
  state. The other members keep their step.

After MAX_CONSECUTIVE_FAILURES skipped steps in a row, or as many breaches in a row of one
member, it raises TwinStalled. Every restart becomes a :class:`TwinEvent` ('diverged' or
'implausible'; level 'error' for the mean model, 'warn' for ensemble members).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drill_twin.integrator.guard import StateGuard
from drill_twin.integrator.simulator import SimulationDiverged


class TwinStalled(RuntimeError):
    """
    The model failed MAX_CONSECUTIVE_FAILURES steps in a row, even from a safe state.

    The configuration cannot be integrated (the clock would otherwise stand still).
    """


MAX_CONSECUTIVE_FAILURES = 100
"""Steps in a row that may fail (each retried once from a safe state) before TwinStalled."""


@dataclass(frozen=True)
class TwinEvent:
    """
    Something the rig should hear about.

    kind: 'impact' (a node touches the wall), 'contact_end', 'lift_off', 'landing',
    'diverged' (a member was reset after a failed step), 'implausible' (a member broke a
    physical bound and was reset), 'member_replaced' (an ensemble member that could not be
    integrated any more was replaced: by a copy of another in a filter, by another's state
    under a fresh germ in open loop), 'command_rejected',
    'ensemble_failed'. level: 'info', 'warn' or 'error'.
    """

    kind: str
    level: str
    time_s: float
    message: str
    values: dict = field(default_factory=dict)


class GuardedSimulator:
    """
    A simulator whose failed or implausible steps restart the members concerned.

    :param driver: what steps the batch (module docstring): its ``simulator`` is the batch.
    :param first_member: the number of its member 0 in event messages (the mean model is 0,
        the ensemble members 1..N).
    :param name: what the batch is called in messages when it holds one member
        ('the mean model') or when any member fails ('ensemble members').
    :param guard: the physical bounds (derived from the simulator's system if None).
    :param on_stalled: what to do with members that broke a bound in MAX_CONSECUTIVE_FAILURES
        steps in a row even from a safe state: called with their indices, it returns {member:
        donor} for those it replaced (an ensemble filter copies another member of its pool,
        :meth:`SequentialFilter.replace_stalled`; the open-loop ensemble copies a member's
        state under a fresh draw of the germ); the others stall the batch (TwinStalled), as
        every such member does without it.
    :param replaced_with: what a replacement takes from its donor, in the event's words.

    Counters: ``resets`` (members restarted), ``failed_steps`` (steps skipped after a
    failed retry), ``breaches`` (member steps that broke a bound).
    """

    def __init__(self, driver, first_member: int, name: str,
                 guard: StateGuard | None = None, on_stalled=None,
                 replaced_with: str = 'its state and law'):
        simulator = driver.simulator
        self.driver = driver
        self.simulator = simulator
        self.on_stalled = on_stalled
        self.replaced_with = replaced_with
        self.first_member = first_member
        self.name = name
        self.guard = guard or StateGuard(simulator.system, simulator.law,
                                         germs=simulator.integrator.germ,
                                         law_scales=simulator.integrator.law_scales)
        self.level = 'error' if first_member == 0 else 'warn'
        self.events: list[TwinEvent] = []
        self.resets = 0
        self.failed_steps = 0
        self.breaches = 0
        self._consecutive_failures = 0
        self._consecutive_breaches = np.zeros(simulator.members, dtype=int)

    def step(self):
        """One step; the StepResult, or None if the step failed even after a restart."""
        for _ in range(2):
            before = self.simulator.state.copy()
            try:
                result = self.driver.step()
            except SimulationDiverged as error:
                self._recover(error)
                continue
            self._consecutive_failures = 0
            self._contain(self.guard.check(self.simulator), before)
            return result
        self._consecutive_failures += 1
        self.failed_steps += 1
        if self._consecutive_failures >= MAX_CONSECUTIVE_FAILURES:
            raise TwinStalled(f'{MAX_CONSECUTIVE_FAILURES} steps in a row failed, even from a '
                              f'safe state, at t = {self.simulator.time_s:.6g} s: the model '
                              f'cannot be integrated with this configuration')
        return None

    def _which(self, members) -> tuple[str, list[int]]:
        numbers = [self.first_member + m for m in members]
        which = self.name if self.simulator.members == 1 else f'{self.name} {numbers}'
        return which, numbers

    def _recover(self, error: SimulationDiverged) -> None:
        members = list(error.members) or list(range(self.simulator.members))
        self.driver.reset_members(members)
        self.resets += len(members)
        which, numbers = self._which(members)
        self.events.append(TwinEvent(
            'diverged', self.level, self.simulator.time_s,
            f'{which} diverged ({error}); restarted from a safe state at the same depth',
            {'members': ' '.join(map(str, numbers)), 'time_s': f'{error.time_s:.6g}'}))

    def _contain(self, reasons: dict[int, str], before) -> None:
        """
        Put the members that broke a bound back to their last good state.

        Restart them from a safe state there (or keep the last good state if that breaks too).
        """
        if not reasons:                           # any run of breaches ends
            self._consecutive_breaches[:] = 0
            return
        breached = np.zeros(self.simulator.members, dtype=bool)
        breached[list(reasons)] = True
        self._consecutive_breaches = np.where(breached, self._consecutive_breaches + 1, 0)
        members = sorted(reasons)
        state = self.simulator.state
        breach = self.simulator.last                # the bit at the breaching step
        at = {m: {'weight_on_bit_n': -float(breach.weight_on_bit_n[m]),
                  'torque_on_bit_nm': float(breach.torque_on_bit_nm[m]),
                  'bit_speed_rad_per_s': float(breach.bit_speed_rad_per_s[m]),
                  'rop_m_per_s': float(breach.rop_m_per_s[m])} for m in members}
        self._restore(members, before)
        self.driver.reset_members(members)
        still = [m for m in self.guard.check(self.simulator) if m in reasons]
        if still:                                 # even the safe state is implausible
            self._restore(still, before)
            self.simulator.reevaluate()
        self.resets += len(members)
        self.breaches += len(members)
        for member in members:
            which, numbers = self._which([member])
            kept = ('kept its last good state (the safe state is implausible too)'
                    if member in still else 'restarted from a safe state at its last good depth')
            bit = at[member]
            self.events.append(TwinEvent(
                'implausible', self.level, state.time_s,
                f'{which}: {reasons[member]} (at WOB {bit["weight_on_bit_n"] / 1e3:.4g} kN, '
                f'TOB {bit["torque_on_bit_nm"] / 1e3:.4g} kN m, bit speed '
                f'{bit["bit_speed_rad_per_s"]:.4g} rad/s, ROP {bit["rop_m_per_s"]:.4g} m/s); '
                f'{kept}',
                {'members': str(numbers[0]), 'reason': reasons[member],
                 'time_s': f'{state.time_s:.6g}',
                 **{key: f'{value:.6g}' for key, value in bit.items()}}))
        self._replace_stalled(reasons)
        worst = int(np.max(self._consecutive_breaches))
        if worst >= MAX_CONSECUTIVE_FAILURES:
            member = int(np.argmax(self._consecutive_breaches))
            which, _ = self._which([member])
            raise TwinStalled(f'{which} broke a physical bound in {worst} steps in a row, even '
                              f'from a safe state, at t = {state.time_s:.6g} s '
                              f'({reasons[member]}): the model cannot represent this '
                              f'configuration or these commands')

    def _replace_stalled(self, reasons: dict[int, str]) -> None:
        """Hand the members stalled on a bound to ``on_stalled``; report those it replaced."""
        stalled = np.flatnonzero(self._consecutive_breaches >= MAX_CONSECUTIVE_FAILURES)
        if self.on_stalled is None or stalled.size == 0:
            return
        replaced = self.on_stalled([int(m) for m in stalled])
        if not replaced:
            return
        simulator = self.simulator
        self.guard.set_germs(simulator.integrator.germ, simulator.integrator.law_scales)
        for member, donor in sorted(replaced.items()):
            self._consecutive_breaches[member] = 0
            which, numbers = self._which([member])
            self.events.append(TwinEvent(
                'member_replaced', 'warn', simulator.time_s,
                f'{which} broke a physical bound in {MAX_CONSECUTIVE_FAILURES} steps in a row '
                f'({reasons.get(member, "")}); replaced by a copy of member '
                f'{self.first_member + donor} ({self.replaced_with})',
                {'members': str(numbers[0]), 'donor': str(self.first_member + donor),
                 'time_s': f'{simulator.time_s:.6g}'}))

    def _restore(self, members, before) -> None:
        state = self.simulator.state
        for name in ('q', 'q_rate', 'q_acceleration'):
            getattr(state, name)[members] = getattr(before, name)[members]

    def take_events(self) -> list[TwinEvent]:
        events, self.events = self.events, []
        return events
