"""
Steps integrated again on finer steps: a failed member's, and one that crosses the wall's kink.

A member whose step fails (no convergence, non-finite state) is integrated again over the
same dt on sub-steps: dt/2, halved after every failure down to dt / 2**SUBSTEP_LEVELS and
doubled back after every success (as far as dt/2, aligned on the step), one member at a time
so that no member depends on the rest of its batch. A step in which a member's nodes touch or
leave the borehole wall is integrated again on dt / ``integration.contact_substeps`` (those
members together), so that the kink of the penalty law does not make the wall gain or lose
energy (docs/LATERAL.md, "Steps at the wall"). The top speed is interpolated linearly over
the step (the top drive's acceleration is constant over it), the hook load is the step's.

:class:`StepRepair` holds the finer integrators (built on first use: steps that need no retry
cost what they did) and the counters.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from drill_twin.model.contact import ContactForces
from drill_twin.model.forces import ForceEvaluation
from drill_twin.integrator.newmark import (BatchState, NewmarkIntegrator, StepResult,
                                           merged_result)

SUBSTEP_LEVELS = 4
"""A failed step is retried on sub-steps down to dt / 2**SUBSTEP_LEVELS (dt/16)."""
STATE_ARRAYS = ('q', 'q_rate', 'q_acceleration', 'hole_u')
"""The per-member arrays of a BatchState."""


class StepRepair:
    """
    The finer integrations of one simulator's steps (module docstring).

    :param integrator: the simulator's integrator (of step ``dt``, s).
    :param members: batch size m.
    :param contact_substeps: ``integration.contact_substeps`` (1: no contact refinement).

    Counters: ``retries`` (member-steps integrated again on sub-steps, all members),
    ``retries_by_member`` (m,), ``substeps`` (sub-steps attempted in those retries, successful
    or not), ``contact_refinements`` (member-steps integrated again on dt / contact_substeps
    because a node touched or left the wall in them).
    """

    def __init__(self, integrator: NewmarkIntegrator, dt: float, members: int,
                 contact_substeps: int):
        self.integrator = integrator
        self.dt = dt
        self.members = members
        self.contact_substeps = contact_substeps
        self._substep_integrators: dict[int, NewmarkIntegrator] = {}
        self._contact_integrator: NewmarkIntegrator | None = None
        self.retries = 0
        self.retries_by_member = np.zeros(members, dtype=int)
        self.substeps = 0
        self.contact_refinements = 0

    def retry(self, state: BatchState, new_state: BatchState, result: StepResult,
              start_speed: float, speed: float, hook_load_n):
        """
        Integrate each failed member of a step from ``state`` again on sub-steps.

        Return (new_state, merged result, retries (m,): sub-steps per member); ``new_state``
        and ``result`` the step's, ``speed`` (rad/s) and ``hook_load_n`` its inputs.
        """
        failed = np.flatnonzero(~result.converged)
        retries = np.zeros(self.members, dtype=int)
        still_failed = []
        forces = result.forces
        for member in failed:
            outcome, attempts = self.substep(state, member, start_speed, speed, hook_load_n)
            retries[member] = attempts
            self.retries += 1
            self.retries_by_member[member] += 1
            self.substeps += attempts
            if outcome is None:
                still_failed.append(member)
                continue
            single, evaluation = outcome
            for name in STATE_ARRAYS:
                getattr(new_state, name)[member] = getattr(single, name)[0]
            forces = with_members(forces, np.array([member]), evaluation)
        self.integrator.forget(failed)
        converged = np.ones(self.members, dtype=bool)
        converged[still_failed] = False
        message = result.message
        if still_failed:
            failed_members = [int(m) for m in still_failed]
            message = (f'{message}; members {failed_members} failed on sub-steps down to '
                       f'dt/{2 ** SUBSTEP_LEVELS} too')
        merged = merged_result(result, success=not still_failed, converged=converged,
                               finite=result.finite | converged, message='' if not still_failed
                               else message, forces=forces,
                               error=np.where(converged & ~result.converged, 0.0, result.error))
        return new_state, merged, retries

    def refine_contact_changes(self, state: BatchState, touching_before: np.ndarray,
                               new_state: BatchState, result: StepResult, start_speed: float,
                               speed: float, hook_load_n):
        """
        Integrate again on dt / contact_substeps the members whose wall contact changed.

        A node that touches or leaves the wall within a step puts the kink of the penalty law
        inside it, where the trapezoidal rule's work is wrong by up to k p (dr - p) / 2 (p the
        penetration at the end that touches, dr the radial travel): finer steps there bring
        the wall's net work to zero (docs/LATERAL.md, "Steps at the wall"). The members
        concerned are integrated together, as one batch on the finer step; if that fails,
        member by member on the retry's sub-steps, and a member that fails even so keeps its
        full step.
        ``touching_before`` (m, n_nodes): the contact flags at ``state``. Return (new_state,
        result).
        """
        after = result.forces.contact.in_contact
        changed = np.flatnonzero(np.any(touching_before != after, axis=1))
        if changed.size == 0:
            return new_state, result
        count = self.contact_substeps
        with np.errstate(invalid='ignore', over='ignore', divide='ignore'):
            outcome = self._fine_steps(state, changed, start_speed, speed, hook_load_n, count)
            if outcome is not None:
                refined, (fine, evaluation) = changed, outcome
            else:
                finest = int(round(math.log2(count)))
                refined, states, evaluations = [], [], []
                for member in changed:
                    single, _ = self.substep(state, member, start_speed, speed, hook_load_n,
                                             finest)
                    if single is not None:
                        refined.append(member)
                        states.append(single[0])
                        evaluations.append(single[1])
                if not refined:
                    return new_state, result
                refined = np.array(refined, dtype=int)
                fine = stack_states(states)
                evaluation = stack_evaluations(evaluations)
        for name in STATE_ARRAYS:
            getattr(new_state, name)[refined] = getattr(fine, name)
        self.contact_refinements += len(refined)
        self.integrator.forget(refined)
        return new_state, merged_result(result, forces=with_members(result.forces, refined,
                                                                    evaluation))

    def _fine_steps(self, state: BatchState, members: np.ndarray, start_speed: float,
                    speed: float, hook_load_n, count: int):
        """
        ``members`` together over [t, t + dt] on ``count`` steps of dt / count.

        (state, forces) of those members, or None if a step fails for any of them.
        """
        integrator = self._contact_integrator
        if integrator is None or integrator.time_step_s != self.dt / count:
            integrator = self._contact_integrator = self.integrator.with_time_step(
                self.dt / count)
        integrator.adopt(self.integrator, members)
        integrator.forget(None)
        fine = state.take(members)
        hook = np.asarray(hook_load_n)[members] if np.ndim(hook_load_n) else hook_load_n
        result = None
        for j in range(count):
            target = start_speed + (speed - start_speed) * (j + 1) / count
            fine, result = integrator.step(fine, target, hook)
            if not result.success:
                return None
        return fine, result.forces

    def substep(self, state: BatchState, member: int, start_speed: float, speed: float,
                hook_load_n, finest: int = 1):
        """
        Member ``member`` over [t, t + dt] from ``state`` on sub-steps of dt / 2**finest or finer.

        ((state, forces), attempts), or (None, attempts) if dt / 2**SUBSTEP_LEVELS fails.
        """
        units = 2 ** SUBSTEP_LEVELS
        single = state.take([member])
        hook = hook_load_n[[member]] if np.ndim(hook_load_n) else hook_load_n
        done, level, attempts, evaluation = 0, finest, 0, None
        while done < units:
            size = units >> level
            integrator = self._substep_integrator(level, member)
            target = start_speed + (speed - start_speed) * (done + size) / units
            new, result = integrator.step(single, target, hook)
            attempts += 1
            if result.success:
                single, evaluation = new, result.forces
                done += size
                if level > finest and done % (2 * size) == 0:
                    level -= 1                          # back up towards the full step
            elif level == SUBSTEP_LEVELS:
                return None, attempts
            else:
                level += 1
        return (single, evaluation), attempts

    def _substep_integrator(self, level: int, member: int) -> NewmarkIntegrator:
        """Return the integrator of dt / 2**level for one member (built once per level)."""
        integrator = self._substep_integrators.get(level)
        if integrator is None:
            integrator = self.integrator.with_time_step(self.dt / 2 ** level)
            self._substep_integrators[level] = integrator
        integrator.adopt(self.integrator, slice(member, member + 1))
        integrator.forget(None)
        return integrator


def with_members(evaluation: ForceEvaluation, members: np.ndarray,
                 rows: ForceEvaluation) -> ForceEvaluation:
    """Return ``evaluation`` with the rows ``members`` (indices) replaced by those of ``rows``."""
    def put(array, row):
        out = array.copy()
        out[members] = row
        return out

    tangent = None
    if evaluation.contact_tangent is not None or rows.contact_tangent is not None:
        shape = evaluation.contact.in_contact.shape + (2, 2)
        mine = (evaluation.contact_tangent if evaluation.contact_tangent is not None
                else np.zeros(shape))
        row = (rows.contact_tangent if rows.contact_tangent is not None
               else np.zeros((len(members),) + shape[1:]))
        tangent = put(mine, row)
    contact = ContactForces(put(evaluation.contact.radial_force_n,
                                rows.contact.radial_force_n),
                            put(evaluation.contact.in_contact, rows.contact.in_contact))
    return replace(evaluation, full=put(evaluation.full, rows.full),
                   modal=put(evaluation.modal, rows.modal),
                   weight_on_bit_n=put(evaluation.weight_on_bit_n, rows.weight_on_bit_n),
                   torque_on_bit_nm=put(evaluation.torque_on_bit_nm, rows.torque_on_bit_nm),
                   rop_m_per_s=put(evaluation.rop_m_per_s, rows.rop_m_per_s),
                   bit_speed_rad_per_s=put(evaluation.bit_speed_rad_per_s,
                                           rows.bit_speed_rad_per_s),
                   lifted=put(evaluation.lifted, rows.lifted),
                   bit_jacobian=put(evaluation.bit_jacobian, rows.bit_jacobian),
                   contact=contact, contact_tangent=tangent)


def stack_states(states: list) -> BatchState:
    """Return one-member states (same time and drive) as one state of their members."""
    first = states[0]
    return replace(first, **{name: np.concatenate([getattr(s, name) for s in states])
                             for name in STATE_ARRAYS})


def stack_evaluations(evaluations: list) -> ForceEvaluation:
    """Return one-member evaluations as one evaluation of their members."""
    first = evaluations[0]

    def stack(name):
        return np.concatenate([getattr(e, name) for e in evaluations])

    tangents = [e.contact_tangent for e in evaluations]
    tangent = None
    if any(t is not None for t in tangents):
        shape = first.contact.in_contact.shape[1:] + (2, 2)
        tangent = np.concatenate([np.zeros((1,) + shape) if t is None else t
                                  for t in tangents])
    contact = ContactForces(np.concatenate([e.contact.radial_force_n for e in evaluations]),
                            np.concatenate([e.contact.in_contact for e in evaluations]))
    return replace(first, **{name: stack(name) for name in (
        'full', 'modal', 'weight_on_bit_n', 'torque_on_bit_nm', 'rop_m_per_s',
        'bit_speed_rad_per_s', 'lifted', 'bit_jacobian')},
        contact=contact, contact_tangent=tangent)
