"""
The state guard: every step of every member checked against physics, ROS-free.

A step the integrator accepts can still be nonsense: a hook load far above the string's
weight flings the string out of the hole, a bit-rock law with absurd constants spins the bit
at 10 000 rad/s. After every step :class:`StateGuard` checks each member against bounds
derived from the configuration (:class:`~drill_twin.integrator.envelope.StringEnvelope`), with the
multiples stated here:

- the state (q, q', q'') and the bit's quantities are finite;
- the bit is in the hole: not above the surface (depth >= 0) and not deeper than the hole's
  bottom plus the contact penetration WOB_bound / k, k the smaller of k_ip and the rock's
  ``bit_rock.contact_stiffness_n_per_m`` (the hole is the simulator's
  ``hole_depth_m`` where it has one, else the deepest the bit has been);
- |ROP| and the top's axial speed <= SPEED_MULTIPLE x the block speed;
- |bit speed| <= SPEED_MULTIPLE x max(the envelope's top-drive speed, the top speed now)
  (stick-slip peaks reach two to three times the top speed);
- |WOB| <= FORCE_MULTIPLE x (WOB_max + Z v_block): the envelope's weight on bit plus the
  impact of a landing at block speed on the bottom section's impedance Z;
- |TOB| <= FORCE_MULTIPLE x the largest torque of the member's bit-rock law over the envelope's
  speeds at the same force scale as the WOB bound, WOB_max + Z v_block (the mean law, or the
  member's random law of Eq. 50: at delta = 0.1 up to 1.2 times the mean law's). The law pairs
  every WOB with a torque: a landing's WOB that the bound accepts brings the torque the law
  gives at that WOB, which is then accepted too (a torque scale taken at
  WOB_max only would reset members, on a landing's TOB, whose WOB is inside its bound);
- with wall contact modelled, every node's radial displacement <= its clearance plus the
  penetration PENETRATION_MULTIPLE x m_e c Omega^2 / k_ip (the wall force that holds the
  heaviest element whirling at the clearance at the envelope's top speed);
- no energy without a source: the kinetic energy of the reduced coordinates (motion relative
  to the driven rotation) <= what the hook and the top drive could have given the string,
  every point moving at the speed bounds above: 1/2 M v^2 axially, 1/2 J w^2 in torsion
  and 1/2 M (c w)^2 in lateral whirl.

:meth:`StateGuard.check` returns the breaching members and why; the caller
(:class:`~drill_twin.integrator.stepping.GuardedSimulator`) treats them as diverged.
"""
from __future__ import annotations

import numpy as np

from drill_twin.integrator.member_measures import measure_members, screen_members
from drill_twin.integrator.envelope import (ENVELOPE_TOP_DRIVE_SPEED_MAX_RAD_PER_S,
                                            PLAUSIBLE_BLOCK_SPEED_M_PER_S, StringEnvelope,
                                            largest_torque_on_bit_nm)

SPEED_MULTIPLE = 5.0
"""Axial and rotation speeds: multiples of the block speed and of the top-drive speed."""
FORCE_MULTIPLE = 3.0
"""WOB and TOB: multiples of the envelope's largest values (landing impact included)."""
PENETRATION_MULTIPLE = 10.0
"""Wall penetration: multiple of the penetration of a whirling element."""
TORQUE_FLOOR_NM = 1.0e3
"""TOB scale when the law gives (almost) none, e.g. with the bit-rock law switched off."""


class StateGuard:
    """
    Bounds of one string's members (see the module docstring).

    :param system: the reduced system the simulator steps.
    :param law: its bit-rock law (for the torque scale).
    :param envelope: the string's scales (derived from ``system`` if None).
    :param germs: (m, 2, 2) the members' random germs, or None (the mean law).
    :param law_scales: (m, 5) the members' factors of the law's a1 ... a5, or None.
    """

    def __init__(self, system, law, envelope: StringEnvelope | None = None, germs=None,
                 law_scales=None):
        config = system.model.config
        self.system = system
        self.envelope = envelope or StringEnvelope.of(system)
        e = self.envelope
        block = PLAUSIBLE_BLOCK_SPEED_M_PER_S
        self.axial_speed_max_m_per_s = SPEED_MULTIPLE * block
        self.impact_weight_on_bit_n = e.weight_on_bit_max_n + e.axial_impedance_n_s_per_m * block
        """The force scale of the WOB and TOB bounds: the envelope's WOB and a landing's (N)."""
        self.weight_on_bit_max_n = FORCE_MULTIPLE * self.impact_weight_on_bit_n
        self.law = law
        self.set_germs(germs, law_scales)
        stiffness = config.borehole.contact_stiffness_n_per_m
        rock = config.bit_rock.contact_stiffness_n_per_m           # None: a rigid rock
        self.bit_penetration_m = self.weight_on_bit_max_n / (
            stiffness if rock is None else min(stiffness, rock))
        self.lateral = config.physics.contact
        mesh = system.model.mesh
        element_mass = mesh.density_kg_per_m3 * mesh.area_m2 * mesh.length_m
        node_mass = np.zeros(mesh.n_nodes)
        node_mass[:-1] += 0.5 * element_mass
        node_mass[1:] += 0.5 * element_mass
        self.clearance_m = system.clearance_m
        whirl = (node_mass * np.maximum(self.clearance_m, 0.0)
                 * ENVELOPE_TOP_DRIVE_SPEED_MAX_RAD_PER_S ** 2)
        self.lateral_max_m = self.clearance_m + PENETRATION_MULTIPLE * np.max(whirl) / stiffness
        self.string_length_m = mesh.total_length_m
        self._clearance_max_m = float(np.max(self.clearance_m))
        axial = system.blocks['axial']
        # The bit's and the top's axial rows of [Phi] over the axial block, and the v and w
        # rows of every node over the bending blocks ((k, n_nodes) each; the bending blocks'
        # rows are v then theta_z, w then theta_y): a check reads the state as it is.
        self._axial_start = axial.columns.start
        self._bit_row = np.ascontiguousarray(axial.shapes[system.bit_node])
        self._top_row = np.ascontiguousarray(system.top_axial_row[axial.columns])
        nodes = system.n_nodes
        self._bending = [(system.blocks[name].columns,
                          np.ascontiguousarray(system.blocks[name].shapes[:nodes].T))
                         for name in ('bending_y', 'bending_z')]
        # Mass-normalised modes give [M_r] = I up to rounding (as the integrator takes it):
        # then the kinetic energy is |q'|^2 / 2, within 1e-9 of the quadratic form.
        identity = np.allclose(system.mass, np.eye(system.size), rtol=0.0, atol=1e-9)
        self._mass = None if identity else system.mass
        self._deepest = None
        self._screen_work = None
        self._screen_top, self._screen_bounds = None, None   # the bounds at a top speed
        self._lateral_max = np.ascontiguousarray(self.lateral_max_m, dtype=float)
        self._no_nodes = np.zeros((0, self._lateral_max.shape[0]))

    def set_germs(self, germs, law_scales=None) -> None:
        """
        Derive the TOB bound from the members' germs (m, 2, 2), or the mean law's (None).

        ``law_scales``: (m, 5) the members' factors of a1 ... a5, or None (the law's). Called
        again when they change (an ensemble filter estimates them).
        """
        speed, force = ENVELOPE_TOP_DRIVE_SPEED_MAX_RAD_PER_S, self.impact_weight_on_bit_n
        if law_scales is None:
            largest = largest_torque_on_bit_nm(self.law, speed, force, germs)
        else:
            largest = np.array([largest_torque_on_bit_nm(
                self.law.scaled(scales), speed, force,
                None if germs is None else germs[i:i + 1])
                for i, scales in enumerate(law_scales)]).reshape(-1)
        self.torque_on_bit_max_nm = FORCE_MULTIPLE * np.maximum(largest, TORQUE_FLOOR_NM)
        """Scalar (mean law) or (m,) (the members' laws) (N m)."""
        self._torque_max = np.ascontiguousarray(np.atleast_1d(self.torque_on_bit_max_nm),
                                                dtype=float)

    def rotation_speed_max(self, top_speed_rad_per_s: float) -> float:
        """Bound of |bit speed| (rad/s) at a top-drive speed."""
        return SPEED_MULTIPLE * max(ENVELOPE_TOP_DRIVE_SPEED_MAX_RAD_PER_S,
                                    abs(top_speed_rad_per_s))

    def kinetic_energy_max(self, top_speed_rad_per_s: float) -> float:
        """Bound of the reduced coordinates' kinetic energy (J) at a top-drive speed."""
        e = self.envelope
        omega = self.rotation_speed_max(top_speed_rad_per_s)
        return 0.5 * (e.string_mass_kg * self.axial_speed_max_m_per_s ** 2
                      + e.polar_inertia_kg_m2 * omega ** 2
                      + e.string_mass_kg * (self._clearance_max_m * omega) ** 2)

    def check(self, simulator) -> dict[int, str]:
        """{member: why} for every member of ``simulator`` whose state breaks a bound."""
        state, forces = simulator.state, simulator.last
        screened = self._screen(simulator, state, forces)
        if screened is not None and not screened.any():
            return {}
        with np.errstate(invalid='ignore', over='ignore'):
            values = self._measure(simulator, state, forces)
            bad = ~values['finite']
            for name, bound in self._bounds(state.top_speed_rad_per_s).items():
                bad |= np.abs(values[name]) > bound
            bad |= values['depth'] < 0.0
            bad |= values['depth'] > values['hole'] + self.bit_penetration_m
            if self.lateral:
                bad |= np.any(values['radius'] > self.lateral_max_m, axis=1)
            reasons = {int(k): self._reason(k, values, state.top_speed_rad_per_s)
                       for k in np.flatnonzero(bad)}
        self._remember(values['depth'], reasons)
        return reasons

    def _screen(self, simulator, state, forces) -> np.ndarray | None:
        """
        Return the members that break a bound, (m,) bools, decided in one compiled pass.

        The same decision as :meth:`check`'s (member_measures.screen_members), which measures
        and words everything only when a member breaks a bound. None where the pass does not
        apply (a mass other than the identity, a simulator without its hole's depth).
        """
        hole = getattr(simulator, 'hole_depth_m', None)
        if self._mass is not None or hole is None:
            return None
        members = state.q.shape[0]
        if self._screen_work is None or self._screen_work.shape != (members,):
            self._screen_work = np.empty(members, dtype=bool)
        bad = self._screen_work
        top = state.top_speed_rad_per_s
        if top != self._screen_top:                 # (the top speed is mostly held)
            self._screen_top = top
            self._screen_bounds = np.array([
                self.string_length_m, self.bit_penetration_m, self.axial_speed_max_m_per_s,
                self.rotation_speed_max(top), self.weight_on_bit_max_n,
                self.kinetic_energy_max(top)])
        bounds = self._screen_bounds
        q = np.ascontiguousarray(state.q)
        v = w = self._no_nodes
        if self.lateral:
            with np.errstate(invalid='ignore', over='ignore'):    # a diverged member's
                v, w = self._node_displacements(q)
        hole = np.asarray(hole, dtype=float)
        if hole.shape != (members,) or not hole.flags.c_contiguous:
            hole = np.full(members, hole)
        screen_members(
            q, np.ascontiguousarray(state.q_rate), np.ascontiguousarray(state.q_acceleration),
            self._axial_start, self._bit_row, self._top_row, forces.rop_m_per_s,
            forces.bit_speed_rad_per_s, forces.weight_on_bit_n, forces.torque_on_bit_nm,
            hole, bounds, self._torque_max, bool(self.lateral), v, w, self._lateral_max, bad)
        return bad

    def _bounds(self, top_speed_rad_per_s: float) -> dict[str, float]:
        """Return the speed, force and energy bounds at a top-drive speed, by measured quantity."""
        axial = self.axial_speed_max_m_per_s
        return {'rop': axial, 'top_axial_speed': axial,
                'bit_speed': self.rotation_speed_max(top_speed_rad_per_s),
                'wob': self.weight_on_bit_max_n, 'tob': self.torque_on_bit_max_nm,
                'kinetic_energy': self.kinetic_energy_max(top_speed_rad_per_s)}

    def _measure(self, simulator, state, forces) -> dict[str, np.ndarray]:
        """Return the checked quantities of every member, shape (m,) ((m, n_nodes) for radius)."""
        q, rate = state.q, state.q_rate
        members = q.shape[0]
        finite = np.empty(members, dtype=bool)
        bit_u, top_rate, kinetic = np.empty(members), np.empty(members), np.empty(members)
        measure_members(np.ascontiguousarray(q), np.ascontiguousarray(rate),
                        np.ascontiguousarray(state.q_acceleration), self._axial_start,
                        self._bit_row, self._top_row, finite, bit_u, top_rate, kinetic)
        rop, omega = forces.rop_m_per_s, forces.bit_speed_rad_per_s
        wob, tob = forces.weight_on_bit_n, forces.torque_on_bit_nm
        finite &= np.isfinite(rop) & np.isfinite(omega) & np.isfinite(wob) & np.isfinite(tob)
        if not finite.all():                     # the others are measured, the bad zeroed
            q = np.where(finite[:, None], q, 0.0)
            rate = np.where(finite[:, None], rate, 0.0)
        if self._mass is not None:
            kinetic = 0.5 * np.sum((rate @ self._mass) * rate, axis=1)
        depth = self.string_length_m + bit_u
        values = {'finite': finite, 'depth': depth, 'hole': self._hole_depth(simulator, depth),
                  'rop': rop, 'top_axial_speed': top_rate, 'bit_speed': omega, 'wob': wob,
                  'tob': tob, 'kinetic_energy': kinetic}
        if self.lateral:
            values['radius'] = np.hypot(*self._node_displacements(q))
        return values

    def _node_displacements(self, q) -> tuple[np.ndarray, np.ndarray]:
        """Return every node's lateral displacements (v, w), (m, n_nodes) each (m)."""
        (y_columns, y_rows), (z_columns, z_rows) = self._bending
        return q[:, y_columns] @ y_rows, q[:, z_columns] @ z_rows

    def _reason(self, k: int, values: dict, top_speed_rad_per_s: float) -> str:
        """Why member k breaks a bound (the first bound it breaks), one phrase."""
        if not values['finite'][k]:
            return 'the state is not finite'
        depth, hole = values['depth'][k], values['hole'][k]
        if depth < 0.0:
            return f'the bit is above the surface (depth {depth:.4g} m)'
        if depth > hole + self.bit_penetration_m:
            return (f'the bit is {depth - hole:.3g} m below the bottom of the hole (contact '
                    f'penetration at most {self.bit_penetration_m:.3g} m)')
        words = {'rop': ('ROP', 'm/s'), 'top_axial_speed': ("the top's axial speed", 'm/s'),
                 'bit_speed': ('bit speed', 'rad/s'), 'wob': ('WOB', 'N'),
                 'tob': ('TOB', 'N m'), 'kinetic_energy': ('kinetic energy', 'J')}
        for name, bound in self._bounds(top_speed_rad_per_s).items():
            value = float(values[name][k])
            bound = float(bound[k]) if np.ndim(bound) else bound
            if abs(value) > bound:
                what, unit = words[name]
                if name == 'kinetic_energy':
                    return (f'kinetic energy {value:.3g} J exceeds what the hook and the top '
                            f'drive could have supplied ({bound:.3g} J)')
                if name == 'wob':                   # the rock's force on the bit, up < 0
                    return (f'WOB {-value:.4g} N (compression > 0) is beyond '
                            f'+-{bound:.4g} N')
                return f'{what} {value:.4g} {unit} is beyond +-{bound:.4g} {unit}'
        radius = values['radius'][k]
        node = int(np.argmax(radius - self.lateral_max_m))
        return (f'a lateral displacement of {radius[node]:.3g} m at node {node} exceeds the '
                f'clearance plus contact penetration ({self.lateral_max_m[node]:.3g} m)')

    def _hole_depth(self, simulator, depth):
        """
        Return the hole's depth per member (m).

        The simulator's, or the deepest plausible bit position so far (today's model drills
        wherever the bit is: the hole is where the bit has been deepest).
        """
        hole = getattr(simulator, 'hole_depth_m', None)
        if hole is not None:
            return np.broadcast_to(np.asarray(hole, dtype=float), depth.shape)
        if self._deepest is None or self._deepest.shape != depth.shape:
            self._deepest = np.full(depth.shape, -np.inf)
        return np.fmax(self._deepest, depth)

    def _remember(self, depth, reasons) -> None:
        """Deepen the remembered hole with the members that passed."""
        if self._deepest is None or self._deepest.shape != depth.shape:
            return
        deeper = np.fmax(self._deepest, depth)
        if reasons:
            failed = list(reasons)
            deeper[failed] = self._deepest[failed]
        self._deepest = deeper
