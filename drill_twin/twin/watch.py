"""
What the twin reports of the mean model's steps: landings, lift-offs, wall impacts.

:class:`EventWatch` compares two steps' force evaluations of member 0 and the simulator's
contact episodes, and appends :class:`~drill_twin.integrator.stepping.TwinEvent` s to the
engine's list.
"""
from __future__ import annotations

from drill_twin.integrator.stepping import TwinEvent

LANDING_PEAK_WINDOW_S = 1.0
"""Longest wait for a landing's peak WOB (s): a bit set down slowly, whose WOB keeps rising,
is reported with the WOB reached by then."""


class EventWatch:
    """
    Events of member 0 of ``simulator`` between two steps, appended to ``events``.

    Landing: one 'landing' per touch-down of the bit on the hole bottom, stamped at the
    touch-down with the bit's axial speed just before it and the impact's peak WOB (the
    first maximum of the WOB after it, within LANDING_PEAK_WINDOW_S; on the rock's spring
    it comes some 70 ms after the touch-down), sent when that peak has passed.
    Wall contact: one 'impact' per contact episode of a node (it opens when the node
    penetrates the wall; integrator/contact_events.py), with the node's depth and the force
    of its first step, and one 'contact_end' when the episode closes (the node is more
    than the hysteresis away from the wall), with the episode's peak force, peak
    penetration and duration: a node rubbing or chattering on the wall is one event.
    Lift-off: one 'lift_off' when the bit leaves the bottom.
    """

    def __init__(self, simulator, events: list):
        self.simulator = simulator
        self.events = events
        self._on_bottom = bool(simulator.on_bottom()[0])
        self._landing = None                  # a landing whose peak WOB is still to come

    def after_step(self, time_s: float, before, now) -> None:
        """Report the events between the forces ``before`` and ``now`` (the step's) at time_s."""
        self._wall_contacts(time_s, now)
        on_bottom = bool(self.simulator.on_bottom()[0])
        landing = self._landing
        if landing is not None:
            compression = -float(now.weight_on_bit_n[0])
            rising = on_bottom and compression >= landing['peak_n']
            if rising:
                landing.update(peak_n=compression, peak_s=time_s)
            if not rising or time_s - landing['time_s'] >= LANDING_PEAK_WINDOW_S:
                self._report_landing()
        if on_bottom != self._on_bottom:
            hole = float(self.simulator.hole_depth_m[0])
            if on_bottom:           # an axial impact on the rock: reported at its peak force
                self._landing = {'time_s': time_s, 'hole_m': hole,
                                 'speed_m_per_s': float(before.rop_m_per_s[0]),
                                 'peak_n': -float(now.weight_on_bit_n[0]), 'peak_s': time_s}
            else:
                self.events.append(TwinEvent(
                    'lift_off', 'warn', time_s, f'the bit lifted off bottom at {hole:.2f} m',
                    {'hole_depth_m': f'{hole:.3f}',
                     'speed_m_per_s': f'{now.rop_m_per_s[0]:.6g}'}))
            self._on_bottom = on_bottom

    def _wall_contacts(self, time_s: float, now) -> None:
        """Report the wall-contact episodes of member 0 that opened or closed in the step."""
        episodes = self.simulator.contact_episodes
        force = now.contact.radial_force_n[0]
        for event in (e for e in episodes.opened if e.member == 0):
            self.events.append(TwinEvent(
                'impact', 'warn', time_s, f'borehole impact at x = {event.depth_m:.1f} m, '
                f'force {force[event.node]:.3g} N',
                {'x_m': f'{event.depth_m:.3f}', 'force_n': f'{force[event.node]:.6g}'}))
        for event in (e for e in episodes.closed if e.member == 0):
            duration = event.end_s - event.start_s
            self.events.append(TwinEvent(
                'contact_end', 'info', time_s, f'contact at x = {event.depth_m:.1f} m ended '
                f'after {duration:.3g} s, peak force {event.peak_force_n:.3g} N',
                {'x_m': f'{event.depth_m:.3f}', 'peak_force_n': f'{event.peak_force_n:.6g}',
                 'peak_penetration_m': f'{event.peak_penetration_m:.6g}',
                 'duration_s': f'{duration:.6g}'}))

    def _report_landing(self) -> None:
        """Report the pending landing: its time, the bit's speed before, the impact's peak WOB."""
        landing, self._landing = self._landing, None
        peak_kn = landing['peak_n'] / 1e3
        self.events.append(TwinEvent(
            'landing', 'warn', landing['time_s'],
            f'the bit landed on bottom at {landing["hole_m"]:.2f} m '
            f'({landing["speed_m_per_s"]:.3g} m/s, peak weight on bit {peak_kn:.3g} kN '
            f'{landing["peak_s"] - landing["time_s"]:.3g} s later)',
            {'hole_depth_m': f'{landing["hole_m"]:.3f}',
             'speed_m_per_s': f'{landing["speed_m_per_s"]:.6g}',
             'peak_weight_on_bit_n': f'{landing["peak_n"]:.6g}',
             'time_to_peak_s': f'{landing["peak_s"] - landing["time_s"]:.6g}'}))
