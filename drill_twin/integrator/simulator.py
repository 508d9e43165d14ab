"""
A batch of drill strings stepped in time under given surface inputs.

:class:`Simulator` holds m members of one drill string (they share the top-drive speed and, by
default, the hook load). What is fixed: the configuration, the reduced system, the integrator
and the observer's rows. What changes: the batch state (``state``: coordinates, rates,
accelerations, hole bottoms, the top's rotation, the hook load of the last step), the forces
of the last step (``last``) and the events and counters since the start. ``step(top_speed,
hook_load)`` advances dt under the surface inputs of that step (``step()`` holds the last
step's), ``observe`` returns the bit, top and station quantities of the last step. The
simulator knows nothing of the machines that set those inputs: the rig
(:mod:`drill_twin.rig`) turns commands into them.

Robust stepping. A member whose step fails (no convergence, non-finite state) is integrated
again over the same dt on sub-steps, one member at a time; only when even dt/16 fails does
``step`` raise :class:`SimulationDiverged` naming the member (the twin then resets it). A step
in which a member's nodes touch or leave the borehole wall is integrated again on finer steps
(:mod:`~drill_twin.integrator.substeps`).

Bit and hole. The hole bottom is the deepest the bit has been (it starts where the bit is):
the bit is on bottom when it is there, off bottom above it (no rock force; a hook load above
the string's weight lifts it), and lands on it again as a unilateral contact
(docs/MODEL-CHOICES.md). ROP is the rate the hole deepens.
"""
from __future__ import annotations

import numpy as np

from drill_twin.config.schema import DrillStringConfig
from drill_twin.integrator import observed_bit
from drill_twin.integrator.contact_events import ContactEpisodes, LiftOffEpisodes, node_gap_m
from drill_twin.integrator.initial_state import initial_coordinates
from drill_twin.integrator.newmark import (ON_BOTTOM_TOLERANCE_M, NewmarkIntegrator, StepResult,
                                           make_step_result)
from drill_twin.integrator.observation import Observation, ObserverRows, observation_of
from drill_twin.integrator.observed_bit import ObservedArrays
from drill_twin.integrator.substeps import SUBSTEP_LEVELS, StepRepair
from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.model.forces import ForceEvaluation, NonlinearForces
from drill_twin.model.reduced_system import ReducedSystem, build_reduced_system
from drill_twin.modal.reduced_basis import modal_analysis

__all__ = ['Observation', 'SUBSTEP_LEVELS', 'SimulationDiverged', 'Simulator']


class SimulationDiverged(RuntimeError):
    """
    A step produced a non-finite state or did not converge.

    ``time_s`` says when and ``members`` which members of the batch failed.
    """

    def __init__(self, message: str, time_s: float, members=()):
        super().__init__(message)
        self.time_s = time_s
        self.members = tuple(int(m) for m in members)

    def __reduce__(self):
        # Picklable across process pools (Monte Carlo workers) with its time and members.
        return (type(self), (str(self), self.time_s, self.members))


class Simulator:
    """
    m members of one drill string, stepped together (see the module docstring).

    :param config: the model.
    :param members: batch size m.
    :param germs: (m, 2, 2) random germs of the bit-rock law, or None (mean model).
    :param system: a prebuilt reduced system of ``config`` (built if None).
    :param law_scales: (m, 5) factors of the law's a1 ... a5 per member, or None (the
        configured law for every member).

    The initial state turns at ``operation.top_drive_speed_rad_per_s`` under the configured
    hook load (``operation.hook_load_n``, or the prestressed state's).
    """

    def __init__(self, config: DrillStringConfig, members: int = 1,
                 germs: np.ndarray | None = None, system: ReducedSystem | None = None,
                 law_scales: np.ndarray | None = None):
        if system is None:
            model, _, basis = modal_analysis(config)
            system = build_reduced_system(model, basis)
        self.config = config
        self.system = system
        self.members = int(members)
        if germs is not None and germs.shape != (self.members, 2, 2):
            raise ValueError(f'germs must have shape ({self.members}, 2, 2)')
        if law_scales is not None and np.shape(law_scales) != (self.members, 5):
            raise ValueError(f'law_scales must have shape ({self.members}, 5)')
        self.forces = NonlinearForces(system)
        integration = config.integration
        self.integrator = NewmarkIntegrator(self.forces, integration.time_step_s,
                                            integration.tolerance, integration.max_iterations,
                                            germs, law_scales)
        self.dt = integration.time_step_s
        self.repair = StepRepair(self.integrator, self.dt, self.members,
                                 integration.contact_substeps)
        self._refines_contact = integration.contact_substeps > 1
        self._no_retries = np.zeros(self.members, dtype=int)
        self._no_retries.flags.writeable = False       # a step without retries: shared zeros
        self.law = BitRockLaw.from_config(config.bit_rock)
        self.observer = ObserverRows(system)
        self.reset_listeners = []
        """Called with the members restarted by :meth:`reset_members` or replaced by
        :meth:`copy_members` (after the change): a rig reseats their drill lines."""
        hook = config.operation.hook_load_n
        hook = system.model.prestress.hook_load_n if hook is None else hook
        speed = config.operation.top_drive_speed_rad_per_s
        self.state = self.integrator.initial_state(*self._initial_coordinates(speed), speed,
                                                   hook)
        self.last = self.integrator.evaluate(self.state)
        # Events: one impact per wall-contact episode, one lift-off per separation
        # of the bit from the rock (hysteresis, integrator/contact_events.py).
        self.contact_episodes = ContactEpisodes(self.members, system.model.mesh.node_x_m,
                                                keep_history=False)
        self.lift_off_episodes = LiftOffEpisodes(self.members)
        self.contact_episodes.prime(self.state.time_s, self.last.contact.in_contact)
        self.lift_off_episodes.prime(self.last.lifted)
        self.contact_onset_count = np.zeros(self.members, dtype=int)
        """Raw onsets of wall contact (every step a node starts touching), (m,)."""
        self.landing_count = np.zeros(self.members, dtype=int)
        self._set_on_bottom(self.on_bottom())
        # The compiled step and observation are loaded now, not in the time loop's first step.
        self.integrator.load_kernels(self.state, self.state.top_speed_rad_per_s, hook)
        self.observe()

    # -- counters ------------------------------------------------------------------------
    @property
    def retries(self) -> int:
        """Member-steps integrated again on sub-steps since the start (all members)."""
        return self.repair.retries

    @property
    def retries_by_member(self) -> np.ndarray:
        """Member-steps integrated again on sub-steps since the start, per member (m,)."""
        return self.repair.retries_by_member

    @property
    def substeps(self) -> int:
        """Sub-steps attempted in those retries (successful or not)."""
        return self.repair.substeps

    @property
    def contact_refinements(self) -> int:
        """
        Member-steps integrated again on dt / integration.contact_substeps (all members).

        Because a node touched or left the wall in them.
        """
        return self.repair.contact_refinements

    @property
    def impact_count(self) -> np.ndarray:
        """Borehole impacts since the start: wall-contact episodes (all nodes), (m,)."""
        return self.contact_episodes.count

    @property
    def lift_off_count(self) -> np.ndarray:
        """Bit lift-offs since the start: lift-off episodes, (m,)."""
        return self.lift_off_episodes.count

    # -- members -------------------------------------------------------------------------
    def reset(self, q: np.ndarray | None = None, q_rate: np.ndarray | None = None,
              hook_load_n=None) -> None:
        """
        Restart from reduced coordinates (m, n) and rates, or from the configured initial state.

        The accelerations balance ``hook_load_n`` (N, scalar or (m,); None: the hook load of
        the last step). The bit is put on the bottom of a hole that ends where the bit is; the
        top speed and angle and the event counters are kept; the time starts again at 0.
        """
        speed = self.state.top_speed_rad_per_s
        if hook_load_n is None:
            hook_load_n = self.state.hook_load_n
        default_q, default_rate = self._initial_coordinates(speed)
        q = default_q if q is None else np.broadcast_to(q, default_q.shape)
        q_rate = default_rate if q_rate is None else np.broadcast_to(q_rate, default_rate.shape)
        self.state = self.integrator.initial_state(q, q_rate, speed, hook_load_n,
                                                   top_angle_rad=self.state.top_angle_rad)
        self.last = self.integrator.evaluate(self.state)
        self._set_on_bottom(self.on_bottom())

    def reset_members(self, members, hook_load_n=None) -> None:
        """
        Restart ``members`` from a safe state.

        The configured initial motion under the current top speed, twisted to carry the steady
        torque on bit, with no lateral deflection, with the bit at its current depth (on or off
        bottom: the hole is kept), its accelerations balancing ``hook_load_n`` (N, scalar or
        (m,); None: the hook load of the last step). The other members are untouched.
        """
        members = np.asarray(members, dtype=int)
        if members.size == 0:
            return
        if hook_load_n is None:
            hook_load_n = self.state.hook_load_n
        speed = self.state.top_speed_rad_per_s
        q, q_rate = self._initial_coordinates(speed, lateral=False, steady_twist=True)
        axial = self.system.blocks['axial']
        bit_row = axial.shapes[self.system.bit_node]             # axial mode shapes at the bit
        bit_position = self.state.q[:, axial.columns] @ bit_row
        # Keep the bit where it was: the rigid mode alone carries it in the safe state.
        q[:, axial.columns.start] = bit_position / bit_row[0]
        hole = self.hole_u()
        off = bit_position < hole - ON_BOTTOM_TOLERANCE_M
        q_rate[off, axial.columns.start] = 0.0                # off bottom: at rest
        fresh = self.integrator.initial_state(q, q_rate, speed, hook_load_n,
                                              top_angle_rad=self.state.top_angle_rad,
                                              hole_u=hole)
        for name in ('q', 'q_rate', 'q_acceleration'):
            getattr(self.state, name)[members] = getattr(fresh, name)[members]
        self.integrator.forget(members)
        self.last = self.integrator.evaluate(self.state)
        for listener in self.reset_listeners:          # e.g. a rig's drill lines
            listener(members)

    def set_members(self, q: np.ndarray, q_rate: np.ndarray, hole_u: np.ndarray,
                    germs: np.ndarray | None = None,
                    law_scales: np.ndarray | None = None) -> None:
        """
        Put the first k members' reduced coordinates, rates and hole bottoms in place.

        An analysis step of data assimilation (drill_twin.assimilation) moves members this way.
        q, q_rate: (k, n); hole_u: (k,) the hole bottom as the bit's axial displacement (m);
        germs: (k, 2, 2) new random germs of those members, or None (kept); law_scales: (k, 5)
        new factors of their law's a1 ... a5, or None (kept). The accelerations
        follow from the equations of motion at the new state, the members' contraction-rate
        history is dropped, and the jump counts as no landing or lift-off.
        """
        q = np.asarray(q, dtype=float)
        k = q.shape[0]
        if not 0 < k <= self.members:
            raise ValueError(f'set_members: {k} members given, the batch has {self.members}')
        if germs is not None:
            if self.integrator.germ is None:
                raise ValueError('set_members: germs given for the mean model (no germs)')
            germ = self.integrator.germ.copy()
            germ[:k] = germs
            self.integrator.germ = germ
        if law_scales is not None:
            scales = (np.ones((self.members, 5)) if self.integrator.law_scales is None
                      else self.integrator.law_scales.copy())
            scales[:k] = law_scales
            self.integrator.law_scales = scales
        state = self.state
        new_q, new_rate, hole = state.q.copy(), state.q_rate.copy(), self.hole_u().copy()
        new_q[:k], new_rate[:k], hole[:k] = q, q_rate, hole_u
        fresh = self.integrator.initial_state(new_q, new_rate, state.top_speed_rad_per_s,
                                              state.hook_load_n,
                                              top_angle_rad=state.top_angle_rad, hole_u=hole)
        for name in ('q', 'q_rate', 'q_acceleration', 'hole_u'):
            getattr(state, name)[:k] = getattr(fresh, name)[:k]
        self.integrator.forget(np.arange(k))
        self.last = self.integrator.evaluate(state)
        self._set_on_bottom(self.on_bottom())

    def copy_members(self, targets, sources, germs=None) -> None:
        """
        Make each member of ``targets`` a copy of the member of ``sources`` beside it (indices).

        The state (q, q', q'', the hole), the random germ and the law's factors are copied; the
        copies' contraction-rate history is dropped and the reset listeners hear of them (a
        rig's drill lines are reseated). What a filter does with a member it cannot
        integrate (drill_twin.assimilation.sequential): it resamples it from the others.
        ``germs`` (k, 2, 2): the copies take these germs instead of their sources' (a fresh
        draw of the prior, for the twin's open-loop ensemble); the new law acts from the next
        step (the copied accelerations are the source's).
        """
        targets = np.asarray(targets, dtype=int)
        sources = np.asarray(sources, dtype=int)
        if targets.shape != sources.shape:
            raise ValueError(f'copy_members: {targets.size} targets, {sources.size} sources')
        integrator = self.integrator
        if germs is not None and integrator.germ is None:
            raise ValueError('copy_members: germs given for a batch without germs')
        if integrator.germ is not None:
            germ = integrator.germ.copy()
            germ[targets] = germ[sources] if germs is None else germs
            integrator.germ = germ
        if integrator.law_scales is not None:
            scales = integrator.law_scales.copy()
            scales[targets] = scales[sources]
            integrator.law_scales = scales
        state = self.state
        for name in ('q', 'q_rate', 'q_acceleration', 'hole_u'):
            values = getattr(state, name)
            if values is not None:
                values[targets] = values[sources]
        integrator.forget(targets)
        self.last = self.integrator.evaluate(state)
        self._set_on_bottom(self.on_bottom())
        for listener in self.reset_listeners:
            listener(targets)

    def reevaluate(self) -> None:
        """Evaluate the forces at the current state again (after it was written in place)."""
        self.last = self.integrator.evaluate(self.state)

    # -- stepping ------------------------------------------------------------------------
    def step(self, top_speed_rad_per_s: float | None = None, hook_load_n=None) -> StepResult:
        """
        Advance dt under the surface inputs of the step.

        ``top_speed_rad_per_s``: the top-drive speed at the end of the step (rad/s; it changes
        linearly over the step); ``hook_load_n``: the hook load over the step (N), one for the
        batch or one per member, shape (m,). None holds the last step's (the state's). A
        member whose step fails is retried on sub-steps (module docstring). Raises
        SimulationDiverged naming the members that fail even on dt/16 (the state of every
        member is then left as it was).
        """
        start = self.state
        start_speed = start.top_speed_rad_per_s
        speed = start_speed if top_speed_rad_per_s is None else top_speed_rad_per_s
        if hook_load_n is None:
            hook_load_n = start.hook_load_n
        elif np.ndim(hook_load_n) and np.shape(hook_load_n) != (self.members,):
            raise ValueError(f'hook loads must have shape ({self.members},), '
                             f'got {np.shape(hook_load_n)}')
        new_state, result = self.integrator.step(start, speed, hook_load_n)
        retries = self._no_retries
        if not result.success:
            # A diverging member's NaN and inf are caught below (SimulationDiverged), not
            # warned of.
            with np.errstate(invalid='ignore', over='ignore', divide='ignore'):
                new_state, result, retries = self.repair.retry(start, new_state, result,
                                                               start_speed, speed, hook_load_n)
        if not result.success:
            self.integrator.discard_last_step()
            raise SimulationDiverged(result.message, new_state.time_s,
                                     np.flatnonzero(~result.converged))
        previous = self.last
        if self._refines_contact and (previous.contact_tangent is not None
                                      or result.forces.contact_tangent is not None):
            # (a node touched before or after the step)
            new_state, result = self.repair.refine_contact_changes(
                start, previous.contact.in_contact, new_state, result, start_speed, speed,
                hook_load_n)
        self.state, self.last = new_state, result.forces
        self._count_events(previous, result)
        return make_step_result(result.success, result.converged, result.finite,
                                result.iterations, result.error, result.message, result.forces,
                                retries, self._on_bottom, result.members_on_bottom,
                                result.members_lifted)

    def _count_events(self, previous: ForceEvaluation, result: StepResult) -> None:
        """Count the step's contact onsets, episodes and landings (``previous``: forces before)."""
        if self.last.contact_tangent is not None or previous.contact_tangent is not None:
            self.contact_onset_count += np.sum(self.last.contact.in_contact
                                               & ~previous.contact.in_contact, axis=1)
        self._count_episodes(result.members_lifted)
        on_bottom = result.on_bottom                  # the kernel's, unless states were merged
        if on_bottom is None:
            on_bottom = self.on_bottom()
        if not self._all_on_bottom:                   # (a bit can land only if one was off)
            self.landing_count += on_bottom & ~self._on_bottom
        self._set_on_bottom(on_bottom, result.members_on_bottom)

    def _set_on_bottom(self, on_bottom: np.ndarray, count: int | None = None) -> None:
        """Keep the members' on-bottom flags (m,) and whether all are set (count: of them)."""
        self._on_bottom = on_bottom
        self._all_on_bottom = (count == self.members if count is not None
                               else bool(on_bottom.all()))

    def _count_episodes(self, lifted: int | None = None) -> None:
        """
        Feed the step's contact flags and bit forces to the episode trackers.

        ``lifted``: how many of the step's lift-off flags are set, when the kernel counted them.
        """
        last, system = self.last, self.system
        state = self.state
        contacts = self.contact_episodes
        if last.contact_tangent is None and not contacts.any_open:    # None: nothing touches
            contacts.update_untouched()
        else:
            contacts.update_from_contact(
                state.time_s, last.contact.in_contact, last.contact.radial_force_n,
                float(system.model.config.borehole.contact_stiffness_n_per_m),
                lambda members, nodes: node_gap_m(system, state.q, members, nodes),
                any_touching=last.contact_tangent is not None)
        self.lift_off_episodes.update(last.lifted, last.weight_on_bit_n, lifted)

    # -- bit and hole --------------------------------------------------------------------
    def hole_u(self) -> np.ndarray:
        """Return the hole bottom as the bit's axial displacement, (m,) (m)."""
        if self.state.hole_u is None:
            return self._bit_u()
        return self.state.hole_u

    @property
    def hole_depth_m(self) -> np.ndarray:
        """The hole's depth per member, (m,) (m): where the bit has drilled to."""
        return self.system.model.mesh.total_length_m + self.hole_u()

    def hole_rop_m_per_s(self, bit_axial_velocity_m_per_s: np.ndarray) -> np.ndarray:
        """
        Return the rate the hole deepens (m/s), (m,).

        The bit's axial velocity while it is on bottom and moving down, else 0 (relative to
        the surface of a lobed bottom, which moves under the bit).
        """
        omega = self.last.bit_speed_rad_per_s if self.last is not None else None
        height, height_rate = self.integrator.bottom_surface(self.state, omega)
        return np.where(self._on_surface(self._bit_u(), height),
                        np.maximum(bit_axial_velocity_m_per_s - height_rate, 0.0), 0.0)

    def on_bottom(self) -> np.ndarray:
        """(m,) True where the bit is on the hole bottom (within 1 um; on the lobes' surface)."""
        if self.integrator.forces.bottom_pattern is None:         # (the time loop's case)
            return self._on_surface(self._bit_u(), 0.0)
        return self._on_surface(self._bit_u(), self.integrator.bottom_surface(self.state)[0])

    def _on_surface(self, bit_u, height) -> np.ndarray:
        """Whether bits at u_bit (m,) are on the rock: at most 1 um above hole + s (m)."""
        return bit_u >= self.hole_u() + height - ON_BOTTOM_TOLERANCE_M

    def _bit_u(self) -> np.ndarray:
        return self.state.q @ self.integrator.bit_axial_row

    @property
    def time_s(self) -> float:
        return self.state.time_s

    # -- observation ---------------------------------------------------------------------
    def observe(self, detailed: int | None = None) -> Observation:
        """
        Measurements at the current state (bit forces from the last converged iterate).

        ``detailed``: the stations, the top torque and the hook motion are computed for the
        first ``detailed`` members only (all by default); the bit quantities always for all.
        The arrays are the observation's own (the contact's are the last evaluation's).
        """
        keep = self.members if detailed is None else min(int(detailed), self.members)
        out = ObservedArrays(1, self.members, len(self.system.stations))
        self.observe_into(out, 0, keep)
        return observation_of(out, keep, self.state, self.last, self.impact_count,
                              self.lift_off_count, self.landing_count)

    def observe_into(self, out: ObservedArrays, k: int, detailed: int | None = None) -> None:
        """
        Write the current observation at record ``k`` of ``out`` (one compiled call).

        The quantities of :meth:`observe`, in the layout of
        :class:`~drill_twin.integrator.observed_bit.ObservedArrays`; ``detailed`` as there.
        """
        state, forces, observer = self.state, self.last, self.observer
        keep = self.members if detailed is None else min(int(detailed), self.members)
        height, height_rate = self.integrator.bottom_surface(state, forces.bit_speed_rad_per_s)
        has_hole = state.hole_u is not None
        # The torque balance of the whole string about x (the rigid rotation costs no
        # strain), the bit's depth and the hole's, the rate the hole deepens (relative to the
        # surface of a lobed bottom, which moves), the depth of cut.
        observed_bit.observe_into(
            k, np.ascontiguousarray(state.q), np.ascontiguousarray(state.q_rate),
            np.ascontiguousarray(state.q_acceleration), keep, observer.operator, observer.hook,
            observer.fields.start, observer.spins.start, observer.driven,
            state.top_speed_rad_per_s, state.top_acceleration_rad_per_s2, forces.full,
            observer.torsion.start, observer.torsion.stop, observer.columns,
            forces.rop_m_per_s, forces.bit_speed_rad_per_s, forces.lifted,
            forces.weight_on_bit_n, forces.torque_on_bit_nm, height, height_rate,
            state.hole_u if has_hole else observer.no_hole, has_hole,
            self.system.model.mesh.total_length_m, self.law.e, state.top_angle_rad,
            forces.contact.radial_force_n, forces.contact.in_contact, self.impact_count,
            self.lift_off_count, self.landing_count, *out.arrays)

    def string_torque_nm(self, member: int = 0) -> float:
        """
        Return T_s of ``member`` at the current state (N m, > 0 when the top drives the string).

        The torque the string takes at its top, ``Observation.top_torque_nm``'s balance.
        """
        return self.observer.string_torque_nm(self.state, self.last, member)

    def _initial_coordinates(self, top_speed: float, lateral: bool = True,
                             steady_twist: bool | None = None):
        """Return the configured initial motion (q, q_rate), (m, n) each (Sect. 2.7)."""
        return initial_coordinates(self.system, self.config, self.law, self.members,
                                   top_speed, lateral, steady_twist)
