"""
A batch of drill strings stepped in time: state, commands, and what an observer measures.

:class:`Simulator` owns the reduced system, the integrator and the current state of m
members (all driven by the same top drive and hook). The twin and the offline runs both use
it: ``step`` advances dt under the current commands, ``observe`` returns the bit, top and
station quantities of the last step.

Robust stepping. A member whose step fails (no convergence, non-finite state) is integrated
again over the same dt on sub-steps: dt/2, halved after every failure down to dt/16 and
doubled back after every success (as far as dt/2, aligned on the step), one member at a
time so that no member depends on the rest of its batch. Only when even dt/16 fails does
``step`` raise :class:`SimulationDiverged` naming the member (the twin then resets it). Steps
that need no retry cost what they did: the sub-step integrators are built on first use.
A step in which a member's nodes touch or leave the borehole wall is integrated again on
dt / ``integration.contact_substeps`` (those members together), so that the kink of the
penalty law does not make the wall gain or lose energy (docs/LATERAL.md, section 4).

Bit and hole. The hole bottom is the deepest the bit has been (it starts where the bit is):
the bit is on bottom when it is there, off bottom above it (no rock force; a hook load above
the string's weight lifts it), and lands on it again as a unilateral contact
(docs/MODEL-CHOICES.md). ROP is the rate the hole deepens.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from drill_twin.config.schema import DrillStringConfig
from drill_twin.integrator import observed_bit
from drill_twin.integrator.observed_bit import ObservedArrays
from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.model.contact import ContactForces
from drill_twin.integrator.contact_events import ContactEpisodes, LiftOffEpisodes, node_gap_m
from drill_twin.rig.drawworks import HookBrake
from drill_twin.rig.drives import drawworks_of
from drill_twin.model.forces import ForceEvaluation, NonlinearForces
from drill_twin.integrator.newmark import (ON_BOTTOM_TOLERANCE_M, BatchState, NewmarkIntegrator,
                                           StepResult, make_step_result, merged_result)
from drill_twin.model.reduced_system import ReducedSystem, build_reduced_system
from drill_twin.modal.reduced_basis import modal_analysis


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


SUBSTEP_LEVELS = 4
"""A failed step is retried on sub-steps down to dt / 2**SUBSTEP_LEVELS (dt/16)."""


@dataclass(frozen=True)
class Observation:
    """
    What the rig and the sensors see after a step, per member (arrays of shape (m,)).

    Bit: depth_m (measured along the string, down from the top's initial position; the same
    as bit_depth_m), rop_m_per_s (the rate the hole deepens: the bit's axial velocity while
    it cuts on bottom, 0 otherwise), angle_rad, speed_rad_per_s, weight_on_bit_n (f_bit, < 0
    in compression), torque_on_bit_nm (t_bit), depth_of_cut_m_per_rad (regularised, ROP
    omega / (omega^2 + e^2)), lifted (no axial force of the rock on the bit: off bottom, or
    touching it without load). Hole: bit_depth_m, hole_depth_m (the deepest the bit has been,
    same reference; never decreases), on_bottom (the bit within 1 um of the hole bottom),
    bit_axial_velocity_m_per_s (du_bit/dt, < 0 moving up). Top: top_torque_nm (the torque
    the top drive applies, > 0 when driving), top_speed_rad_per_s, top_angle_rad (shared),
    hook_load_n (shared, or (m,) per member), hook_position_m, hook_velocity_m_per_s (the
    top's axial displacement and velocity). Stations (m, n_stations, 3) for the fields (u, v, w):
    station_displacement_m, station_velocity_m_per_s, station_acceleration_m_per_s2;
    station_spin_rate_rad_per_s (m, n_stations, 3) for
    (theta_x', theta_y', theta_z'). Wall: contact_force_n (m, n_nodes) radial force,
    in_contact (m, n_nodes). Events since the start: impacts_so_far (wall-contact episodes
    over all nodes: one per episode, not per step touching, dynamics/contact_events.py),
    lift_offs_so_far (lift-off episodes of the bit) and landings_so_far (the bit tags the hole
    bottom after being off bottom), (m,).
    """

    time_s: float
    depth_m: np.ndarray
    rop_m_per_s: np.ndarray
    angle_rad: np.ndarray
    speed_rad_per_s: np.ndarray
    weight_on_bit_n: np.ndarray
    torque_on_bit_nm: np.ndarray
    depth_of_cut_m_per_rad: np.ndarray
    lifted: np.ndarray
    top_torque_nm: np.ndarray
    top_speed_rad_per_s: float
    top_angle_rad: float
    hook_load_n: float | np.ndarray
    hook_position_m: np.ndarray
    hook_velocity_m_per_s: np.ndarray
    station_displacement_m: np.ndarray
    station_velocity_m_per_s: np.ndarray
    station_acceleration_m_per_s2: np.ndarray
    station_spin_rate_rad_per_s: np.ndarray
    contact_force_n: np.ndarray
    in_contact: np.ndarray
    impacts_so_far: np.ndarray
    lift_offs_so_far: np.ndarray
    bit_depth_m: np.ndarray | None = None
    hole_depth_m: np.ndarray | None = None
    on_bottom: np.ndarray | None = None
    bit_axial_velocity_m_per_s: np.ndarray | None = None
    landings_so_far: np.ndarray | None = None


class TopDrive:
    """The top-drive speed follows its command at a bounded acceleration (rad/s^2)."""

    def __init__(self, speed_rad_per_s: float, max_acceleration_rad_per_s2: float):
        self.speed_rad_per_s = float(speed_rad_per_s)
        self.max_acceleration = float(max_acceleration_rad_per_s2)

    def advance(self, command_rad_per_s: float, dt: float) -> float:
        change = command_rad_per_s - self.speed_rad_per_s
        limit = self.max_acceleration * dt
        self.speed_rad_per_s += min(max(change, -limit), limit)
        return self.speed_rad_per_s


class Simulator:
    """
    m members of one drill string, stepped together (see the module docstring).

    :param config: the model.
    :param members: batch size m.
    :param germs: (m, 2, 2) random germs of the bit-rock law, or None (mean model).
    :param system: a prebuilt reduced system of ``config`` (built if None).
    :param law_scales: (m, 5) factors of the law's a1 ... a5 per member, or None (the
        configured law for every member).
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
        self._substep_integrators: dict[int, NewmarkIntegrator] = {}
        self._refines_contact = config.integration.contact_substeps > 1
        self._no_retries = np.zeros(self.members, dtype=int)
        self._no_retries.flags.writeable = False       # a step without retries: shared zeros
        self._contact_integrator: NewmarkIntegrator | None = None
        self.law = BitRockLaw.from_config(config.bit_rock)
        self.dt = integration.time_step_s
        self.reset_listeners = []
        """Called with the members restarted by :meth:`reset_members` (after the restart)."""
        prestress = system.model.prestress
        hook = config.operation.hook_load_n
        self.hook_load_command_n = prestress.hook_load_n if hook is None else hook
        self._step_hook_load_n = self.hook_load_command_n
        """The hook load applied over the current step (the brake's where it holds the top)."""
        self._hook_brake = None
        self.hook_load_through_line = False
        """True while drill lines pull the members' hook loads (a followed block)."""
        speed = config.operation.top_drive_speed_rad_per_s
        self.top_drive = TopDrive(speed, config.operation.top_drive_acceleration_rad_per_s2)
        self.top_speed_command_rad_per_s = speed
        self.state = self.integrator.initial_state(*self._initial_coordinates(speed), speed,
                                                   self.hook_load_command_n)
        self.last = self._evaluate(self.state)
        # Events (issue 12): one impact per wall-contact episode, one lift-off per separation
        # of the bit from the rock (hysteresis, dynamics/contact_events.py).
        self.contact_episodes = ContactEpisodes(self.members, system.model.mesh.node_x_m,
                                                keep_history=False)
        self.lift_off_episodes = LiftOffEpisodes(self.members)
        self.contact_episodes.prime(self.state.time_s, self.last.contact.in_contact)
        self.lift_off_episodes.prime(self.last.lifted)
        self.contact_onset_count = np.zeros(self.members, dtype=int)
        """Raw onsets of wall contact (every step a node starts touching), (m,)."""
        self.landing_count = np.zeros(self.members, dtype=int)
        self.retries = 0
        """Member-steps integrated again on sub-steps since the start (all members)."""
        self.retries_by_member = np.zeros(self.members, dtype=int)
        self.substeps = 0
        """Sub-steps attempted in those retries (successful or not)."""
        self.contact_refinements = 0
        """Member-steps integrated again on dt / integration.contact_substeps because a node
        touched or left the wall in them (all members)."""
        self._set_on_bottom(self.on_bottom())
        self._observer = None
        # The compiled step and observation are loaded now, not in the time loop's first step.
        self.integrator.load_kernels(self.state, self.state.top_speed_rad_per_s,
                                     self.hook_load_command_n)
        self.observe()
        # The rig's drives (issue 13, docs/DRIVES.md): with top_drive.mode dynamic or a
        # drawworks mode other than hook_load, they take over self.top_drive; else no change.
        from drill_twin.rig.drives import attach_drives
        attach_drives(self)

    # -- commands ------------------------------------------------------------------------
    def set_top_drive_speed(self, rad_per_s: float) -> None:
        """Set the top-drive speed command (rad/s), followed from the next step on."""
        self.top_speed_command_rad_per_s = float(rad_per_s)

    def _applied_hook_load(self):
        """
        Return the hook load of the coming step (N, scalar or (m,)).

        The command; in ``hook_load`` mode (no drawworks, no followed block) held by the drum's
        brake where it would move the top faster than ``drawworks.block_speed_max_m_per_s``
        (:class:`~drill_twin.rig.drawworks.HookBrake`).
        """
        command = self.hook_load_command_n
        if self.hook_load_through_line or drawworks_of(self) is not None:
            return command
        if self._hook_brake is None:
            speed_max = self.config.drawworks.block_speed_max_m_per_s
            if speed_max is None:
                return command
            self._hook_brake = HookBrake(self, speed_max)
        return self._hook_brake.hook_load(command)

    def set_hook_load(self, newton) -> None:
        """
        Set the hook load command (N), applied from the next step on.

        One value for the whole batch, or one per member, shape (m,) (each member's own drill
        line, :class:`~drill_twin.rig.drawworks.FollowedBlock`).
        """
        if np.ndim(newton) == 0:
            self.hook_load_command_n = float(newton)
            return
        loads = np.array(newton, dtype=float)
        if loads.shape != (self.members,):
            raise ValueError(f'hook loads must have shape ({self.members},), got {loads.shape}')
        self.hook_load_command_n = loads

    def reset(self, q: np.ndarray | None = None, q_rate: np.ndarray | None = None) -> None:
        """
        Restart from reduced coordinates (m, n) and rates, or from the configured initial state.

        The bit is put on the bottom of a hole that ends where the bit is; the commands, the
        top-drive angle and the event counters are kept.
        """
        speed = self.top_drive.speed_rad_per_s
        default_q, default_rate = self._initial_coordinates(speed)
        q = default_q if q is None else np.broadcast_to(q, default_q.shape)
        q_rate = default_rate if q_rate is None else np.broadcast_to(q_rate, default_rate.shape)
        angle = self.state.top_angle_rad
        self.state = self.integrator.initial_state(q, q_rate, speed, self.hook_load_command_n,
                                                   top_angle_rad=angle)
        self.state.time_s = self.time_s
        self.last = self._evaluate(self.state)
        self._set_on_bottom(self.on_bottom())

    def reset_members(self, members) -> None:
        """
        Restart ``members`` from a safe state.

        The configured initial motion under the current top speed, twisted to carry the steady
        torque on bit, with no lateral deflection, with the bit at its current depth (on or off
        bottom: the hole is kept). The other members are untouched.
        """
        members = np.asarray(members, dtype=int)
        if members.size == 0:
            return
        speed = self.top_drive.speed_rad_per_s
        q, q_rate = self._initial_coordinates(speed, lateral=False, steady_twist=True)
        axial = self.system.blocks['axial']
        bit_row = axial.shapes[self.system.bit_node]             # axial mode shapes at the bit
        bit_position = self.state.q[:, axial.columns] @ bit_row
        # Keep the bit where it was: the rigid mode alone carries it in the safe state.
        q[:, axial.columns.start] = bit_position / bit_row[0]
        hole = self.hole_u()
        off = bit_position < hole - ON_BOTTOM_TOLERANCE_M
        q_rate[off, axial.columns.start] = 0.0                # off bottom: at rest
        fresh = self.integrator.initial_state(q, q_rate, speed, self.hook_load_command_n,
                                              top_angle_rad=self.state.top_angle_rad,
                                              hole_u=hole)
        for name in ('q', 'q_rate', 'q_acceleration'):
            getattr(self.state, name)[members] = getattr(fresh, name)[members]
        self.integrator.forget(members)
        self.last = self._evaluate(self.state)
        if (after_reset := getattr(self.top_drive, 'after_reset', None)) is not None:
            after_reset()                              # a drawworks puts its block back
        for listener in self.reset_listeners:          # e.g. an ensemble's lines
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
        self.last = self._evaluate(state)
        self._set_on_bottom(self.on_bottom())

    def copy_members(self, targets, sources, germs=None) -> None:
        """
        Make each member of ``targets`` a copy of the member of ``sources`` beside it (indices).

        The state (q, q', q'', the hole), the random germ and the law's factors are copied; the
        copies' contraction-rate history is dropped and the reset listeners hear of them (an
        ensemble's drill lines are reseated). What a filter does with a member it cannot
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
        self.last = self._evaluate(state)
        self._set_on_bottom(self.on_bottom())
        for listener in self.reset_listeners:
            listener(targets)

    # -- stepping ------------------------------------------------------------------------
    def step(self) -> StepResult:
        """
        Advance dt; a member whose step fails is retried on sub-steps (module docstring).

        Raises SimulationDiverged naming the members that fail even on dt/16 (the state of
        every member is then left as it was).
        """
        start_speed = self.state.top_speed_rad_per_s
        speed = self.top_drive.advance(self.top_speed_command_rad_per_s, self.dt)
        self._step_hook_load_n = self._applied_hook_load()
        new_state, result = self.integrator.step(self.state, speed, self._step_hook_load_n)
        retries = self._no_retries
        if not result.success:
            # A diverging member's NaN and inf are caught below (SimulationDiverged), not
            # warned of.
            with np.errstate(invalid='ignore', over='ignore', divide='ignore'):
                new_state, result, retries = self._retry(new_state, result, start_speed, speed)
        if not result.success:
            self.integrator.discard_last_step()
            self.top_drive.speed_rad_per_s = start_speed
            raise SimulationDiverged(result.message, new_state.time_s,
                                     np.flatnonzero(~result.converged))
        previous = self.last
        if self._refines_contact and (previous.contact_tangent is not None
                                      or result.forces.contact_tangent is not None):
            # (a node touched before or after the step)
            new_state, result = self._refine_contact_changes(new_state, result, start_speed,
                                                             speed)
        self.state, self.last = new_state, result.forces
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
        return make_step_result(result.success, result.converged, result.finite,
                                result.iterations, result.error, result.message, result.forces,
                                retries, on_bottom, result.members_on_bottom,
                                result.members_lifted)

    def _set_on_bottom(self, on_bottom: np.ndarray, count: int | None = None) -> None:
        """Keep the members' on-bottom flags (m,) and whether all are set (count: of them)."""
        self._on_bottom = on_bottom
        self._all_on_bottom = (count == self.members if count is not None
                               else bool(on_bottom.all()))

    @property
    def impact_count(self) -> np.ndarray:
        """Borehole impacts since the start: wall-contact episodes (all nodes), (m,)."""
        return self.contact_episodes.count

    @property
    def lift_off_count(self) -> np.ndarray:
        """Bit lift-offs since the start: lift-off episodes, (m,)."""
        return self.lift_off_episodes.count

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

    def _retry(self, new_state: BatchState, result: StepResult, start_speed: float,
               speed: float):
        """Integrate each failed member again on sub-steps; the merged state and result."""
        failed = np.flatnonzero(~result.converged)
        retries = np.zeros(self.members, dtype=int)
        still_failed = []
        forces = result.forces
        for member in failed:
            outcome, attempts = self._substep(member, start_speed, speed)
            retries[member] = attempts
            self.retries += 1
            self.retries_by_member[member] += 1
            self.substeps += attempts
            if outcome is None:
                still_failed.append(member)
                continue
            state, evaluation = outcome
            for name in ('q', 'q_rate', 'q_acceleration', 'hole_u'):
                getattr(new_state, name)[member] = getattr(state, name)[0]
            forces = _with_member(forces, member, evaluation)
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

    def _refine_contact_changes(self, new_state: BatchState, result: StepResult,
                                start_speed: float, speed: float):
        """
        Integrate again on dt / contact_substeps the members whose wall contact changed.

        A node that touches or leaves the wall within a step puts the kink of the penalty law
        inside it, where the trapezoidal rule's work is wrong by up to k p (dr - p) / 2 (p the
        penetration at the end that touches, dr the radial travel): finer steps there bring
        the wall's net work to zero (docs/LATERAL.md, section 4). The members concerned are
        integrated together, as one batch on the finer step; if that fails, member by member
        on the retry's sub-steps, and a member that fails even so keeps its full step.
        Called when a node touched the wall before or after the step.
        """
        before = self.last.contact.in_contact
        after = result.forces.contact.in_contact
        changed = np.flatnonzero(np.any(before != after, axis=1))
        if changed.size == 0:
            return new_state, result
        count = self.config.integration.contact_substeps
        with np.errstate(invalid='ignore', over='ignore', divide='ignore'):
            outcome = self._fine_steps(changed, start_speed, speed, count)
            if outcome is not None:
                refined, (state, evaluation) = changed, outcome
            else:
                finest = int(round(math.log2(count)))
                refined, states, evaluations = [], [], []
                for member in changed:
                    single, _ = self._substep(member, start_speed, speed, finest)
                    if single is not None:
                        refined.append(member)
                        states.append(single[0])
                        evaluations.append(single[1])
                if not refined:
                    return new_state, result
                refined = np.array(refined, dtype=int)
                state = _stack_states(states)
                evaluation = _stack_evaluations(evaluations)
        for name in ('q', 'q_rate', 'q_acceleration', 'hole_u'):
            getattr(new_state, name)[refined] = getattr(state, name)
        self.contact_refinements += len(refined)
        self.integrator.forget(refined)
        return new_state, merged_result(result, forces=_with_members(result.forces, refined,
                                                                     evaluation))

    def _fine_steps(self, members: np.ndarray, start_speed: float, speed: float, count: int):
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
        state = self.state.take(members)
        hook = self._step_hook_load_n
        hook = np.asarray(hook)[members] if np.ndim(hook) else hook
        result = None
        for j in range(count):
            target = start_speed + (speed - start_speed) * (j + 1) / count
            state, result = integrator.step(state, target, hook)
            if not result.success:
                return None
        return state, result.forces

    def _substep(self, member: int, start_speed: float, speed: float, finest: int = 1):
        """
        Member ``member`` over [t, t + dt] on sub-steps of dt / 2**finest or finer.

        ((state, forces), attempts), or (None, attempts) if dt / 2**SUBSTEP_LEVELS fails. The
        top speed is interpolated linearly (the top drive's acceleration is constant over the
        step).
        """
        units = 2 ** SUBSTEP_LEVELS
        state = self.state.take([member])
        hook = self._step_hook_load_n
        hook = hook[[member]] if np.ndim(hook) else hook
        done, level, attempts, evaluation = 0, finest, 0, None
        while done < units:
            size = units >> level
            integrator = self._substep_integrator(level, member)
            target = start_speed + (speed - start_speed) * (done + size) / units
            new, result = integrator.step(state, target, hook)
            attempts += 1
            if result.success:
                state, evaluation = new, result.forces
                done += size
                if level > finest and done % (2 * size) == 0:
                    level -= 1                          # back up towards the full step
            elif level == SUBSTEP_LEVELS:
                return None, attempts
            else:
                level += 1
        return (state, evaluation), attempts

    def _substep_integrator(self, level: int, member: int) -> NewmarkIntegrator:
        """Return the integrator of dt / 2**level for one member (built once per level)."""
        integrator = self._substep_integrators.get(level)
        if integrator is None:
            integrator = self.integrator.with_time_step(self.dt / 2 ** level)
            self._substep_integrators[level] = integrator
        integrator.adopt(self.integrator, slice(member, member + 1))
        integrator.forget(None)
        return integrator

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
        floats, flags, stations = out.floats[:, 0], out.flags[:, 0], out.stations[:, 0, :keep]
        state, forces = self.state, self.last
        depth = floats[observed_bit.BIT_DEPTH]
        return Observation(
            time_s=state.time_s,
            depth_m=depth,
            rop_m_per_s=floats[observed_bit.ROP],
            angle_rad=floats[observed_bit.ANGLE],
            speed_rad_per_s=floats[observed_bit.SPEED],
            weight_on_bit_n=floats[observed_bit.WOB],
            torque_on_bit_nm=floats[observed_bit.TOB],
            depth_of_cut_m_per_rad=floats[observed_bit.DEPTH_OF_CUT],
            lifted=flags[observed_bit.LIFTED],
            top_torque_nm=floats[observed_bit.TOP_TORQUE, :keep],
            top_speed_rad_per_s=state.top_speed_rad_per_s,
            top_angle_rad=state.top_angle_rad,
            hook_load_n=state.hook_load_n,
            hook_position_m=floats[observed_bit.HOOK_POSITION, :keep],
            hook_velocity_m_per_s=floats[observed_bit.HOOK_VELOCITY, :keep],
            station_displacement_m=stations[0],
            station_velocity_m_per_s=stations[1],
            station_acceleration_m_per_s2=stations[2],
            station_spin_rate_rad_per_s=stations[3],
            contact_force_n=forces.contact.radial_force_n,
            in_contact=forces.contact.in_contact,
            impacts_so_far=self.impact_count.copy(),
            lift_offs_so_far=self.lift_off_count.copy(),
            bit_depth_m=depth,
            hole_depth_m=floats[observed_bit.HOLE_DEPTH],
            on_bottom=flags[observed_bit.ON_BOTTOM],
            bit_axial_velocity_m_per_s=floats[observed_bit.AXIAL_VELOCITY],
            landings_so_far=self.landing_count.copy(),
        )

    def observe_into(self, out: ObservedArrays, k: int, detailed: int | None = None) -> None:
        """
        Write the current observation at record ``k`` of ``out`` (one compiled call).

        The quantities of :meth:`observe`, in the layout of
        :class:`~drill_twin.integrator.observed_bit.ObservedArrays`; ``detailed`` as there.
        """
        state, forces = self.state, self.last
        observer = self._observer
        if observer is None:
            observer = self._observer = _Observer(self.system)
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

    # -- initial state -------------------------------------------------------------------
    def _initial_coordinates(self, top_speed: float, lateral: bool = True,
                             steady_twist: bool | None = None):
        """Rigid axial and rotation speed plus a lateral deflection (Sect. 2.7)."""
        system, config = self.system, self.config
        if steady_twist is None:
            steady_twist = config.initial_conditions.steady_twist
        n, m = system.size, self.members
        q = np.zeros((m, n))
        q_rate = np.zeros((m, n))
        axial = system.blocks['axial']
        if config.physics.bit_rock and np.any(system.basis.rigid):
            rop = float(self.law.steady_rop(top_speed,
                                            system.model.prestress.static_weight_on_bit_n))
            rigid_column = axial.columns.start                 # the rigid mode comes first
            q_rate[:, rigid_column] = rop / axial.shapes[system.bit_node, 0]
        if steady_twist and config.physics.bit_rock:
            q[:, system.blocks['torsional'].columns] = self._steady_twist(top_speed)
        amplitude = config.initial_conditions.lateral_deflection_m if lateral else 0.0
        bending = system.blocks['bending_y']
        if amplitude > 0 and bending.shapes.shape[1] > 0:
            nodes = system.n_nodes
            if config.initial_conditions.lateral_shape == 'first_lateral_mode':
                shape = np.zeros(bending.shapes.shape[1])
                shape[0] = 1.0
            else:                    # half sine over the string, or over the BHA only
                x = system.model.mesh.node_x_m
                start = 0.0
                if config.initial_conditions.lateral_shape == 'bha_half_sine':
                    start = x[-1] - config.sections[-1].length_m
                length = x[-1] - start
                inside = x >= start - 1e-9
                phase = math.pi * (x - start) / length
                target = np.zeros(2 * nodes)
                target[:nodes] = np.where(inside, np.sin(phase), 0.0)
                target[nodes:] = np.where(inside, (math.pi / length) * np.cos(phase), 0.0)
                mass = system.model.total_mass[np.ix_(system.permutation[bending.rows],
                                                      system.permutation[bending.rows])]
                shape = bending.shapes.T @ (mass @ target)
            lateral = bending.shapes[:nodes] @ shape
            q[:, bending.columns] = amplitude / np.max(np.abs(lateral)) * shape
        return q, q_rate

    def _steady_twist(self, top_speed: float) -> np.ndarray:
        """
        Return the torsional coordinates that carry the steady torque on bit and the drag.

        The drag is that of the spinning string; the coordinates are in static equilibrium
        (K_r q = Phi^T f on the torsional block).
        """
        system = self.system
        torsion = system.blocks['torsional']
        wob = system.model.prestress.static_weight_on_bit_n
        torque = float(self.law.steady_torque(top_speed, wob))
        load = (torsion.shapes[system.bit_node] * torque
                - system.damping_driven[torsion.columns] * top_speed)
        stiffness = system.stiffness[torsion.columns, torsion.columns]
        return np.linalg.solve(stiffness, load)

    def _evaluate(self, state: BatchState) -> ForceEvaluation:
        return self.integrator.evaluate(state)


class _Observer:
    """
    What :meth:`Simulator.observe` measures, as rows on the reduced coordinates.

    A row r of the field-wise DOFs reads r . (Phi q) = (Phi^T r) . q, plus r . psi theta' for
    the rates and accelerations (the driven rotation moves the theta_x DOFs).

    Columns of ``q @ operator``: hook (the top's axial DOF), the stations' (u, v, w) (``fields``,
    station-major), their (theta_x, theta_y, theta_z) (``spins``), the torque balance's mass
    and damping rows, the bit's axial displacement and rotation. ``columns``: those last four
    (``observed_bit.derive``'s); ``torsion``: the torsional field's DOFs; ``no_hole``: the
    hole :func:`observed_bit.observe_into` is handed when the state has none.
    """

    def __init__(self, system: ReducedSystem):
        n_dofs = system.n_dofs
        rows = [np.eye(1, n_dofs, 0)[0]]                      # the hook: u at the top
        stations = system.stations
        rows += [station.rows[k] for station in stations for k in (0, 1, 2)]
        rows += [station.rows[k] for station in stations for k in (3, 4, 5)]
        rows += [system.driven_rows['mass'], system.driven_rows['damping']]
        physical = np.asarray(rows)                           # (k, n_dofs)
        bit = system.bit_node
        axial, torsion = system.blocks['axial'], system.blocks['torsional']
        reduced = system.physical(np.eye(system.size)) @ physical.T      # (n, k)
        bit_rows = np.zeros((system.size, 2))
        bit_rows[axial.columns, 0] = axial.shapes[bit]
        bit_rows[torsion.columns, 1] = torsion.shapes[bit]
        self.operator = np.ascontiguousarray(np.hstack([reduced, bit_rows]))
        count = 3 * len(stations)
        self.hook = 0
        self.fields = slice(1, 1 + count)
        self.spins = slice(1 + count, 1 + 2 * count)
        self.mass, self.damping = 1 + 2 * count, 2 + 2 * count
        self.bit_u, self.bit_angle = 3 + 2 * count, 4 + 2 * count
        self.driven = np.zeros(self.operator.shape[1])
        self.driven[:physical.shape[0]] = physical[:, system.field(1)].sum(axis=1)
        self.torsion = system.field(1)
        self.columns = np.array([self.mass, self.damping, self.bit_u, self.bit_angle],
                                dtype=np.int64)
        self.no_hole = np.empty(0)


def _with_member(evaluation: ForceEvaluation, member: int,
                 single: ForceEvaluation) -> ForceEvaluation:
    """Return ``evaluation`` with row ``member`` replaced by the one-member ``single``."""
    return _with_members(evaluation, np.array([member]), single)


def _with_members(evaluation: ForceEvaluation, members: np.ndarray,
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


def _stack_states(states: list) -> BatchState:
    """Return one-member states (same time and drive) as one state of their members."""
    first = states[0]
    return replace(first, **{name: np.concatenate([getattr(s, name) for s in states])
                             for name in ('q', 'q_rate', 'q_acceleration', 'hole_u')})


def _stack_evaluations(evaluations: list) -> ForceEvaluation:
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
