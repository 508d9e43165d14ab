"""
The twin node's command intake (ROS-free): commands checked, counted, and held for a tick.

A command taken from its topic (:data:`drill_twin.interface.COMMANDS`) goes to the
:class:`~drill_twin.twin.engine.TwinEngine` method that checks and applies it (it acts from
the next model step; the engine counts it as received or rejected). The intake holds the
values taken since the last tick (each one echoed once that tick has stepped), counts those
superseded (a later command on the same topic came before the tick) and those dropped on the
way (gaps in the publisher's sequence numbers).
"""
from __future__ import annotations

from collections.abc import Callable

from drill_twin import interface as itf

ENGINE_COMMANDS = {
    itf.CMD_TOP_DRIVE_SPEED: 'set_top_drive_speed', itf.CMD_HOOK_LOAD: 'set_hook_load',
    itf.CMD_TOP_DRIVE_MODE: 'set_top_drive_mode',
    itf.CMD_TOP_DRIVE_CONTROLLER: 'set_top_drive_controller',
    itf.CMD_TOP_DRIVE_TORQUE_LIMIT: 'set_top_drive_torque_limit',
    itf.CMD_AXIAL_MODE: 'set_axial_mode', itf.CMD_BLOCK_VELOCITY: 'set_block_velocity',
    itf.CMD_WOB_SETPOINT: 'set_weight_on_bit_setpoint'}
"""Command topic -> the TwinEngine method that checks and applies it."""


class CommandIntake:
    """
    Commands on their way into the engine (see the module docstring).

    :param engine: the :class:`~drill_twin.twin.engine.TwinEngine` the commands act on.
    """

    def __init__(self, engine):
        self.engine = engine
        self.pending: dict[str, object] = {}
        """Topic -> the value taken since the last tick (acts from the next step)."""
        self.superseded = 0
        """Commands taken but replaced by a later one before any step used them."""
        self.dropped = 0
        """Commands lost on the way (gaps in the publishers' sequence numbers)."""
        self._sequence: dict[str, int] = {}        # last publication sequence number, by topic

    def count_gap(self, topic: str, sequence: int | None,
                  publisher_count: Callable[[], int]) -> None:
        """
        Count the commands lost before this one of ``topic``.

        ``sequence``: its publication sequence number (None if the middleware gives none).
        Gaps are counted while one publisher sends the topic (``publisher_count``, asked only
        at a gap): the numbers of several publishers interleave.
        """
        if sequence is None:
            return
        last = self._sequence.get(topic)
        if last is not None and sequence > last + 1 and publisher_count() == 1:
            self.dropped += sequence - last - 1
        self._sequence[topic] = sequence

    def take(self, topic: str, value) -> None:
        """
        Hand a command to the engine; it acts from the next model step.

        Raises :class:`~drill_twin.twin.engine.CommandRejected` (the previous command stays).
        """
        getattr(self.engine, ENGINE_COMMANDS[topic])(value)
        if topic in self.pending:                   # the previous one never took effect
            self.superseded += 1
        self.pending[topic] = value

    def applied(self) -> dict:
        """Return the commands the next steps act on ({topic: value}, a copy)."""
        return dict(self.pending)

    def stepped(self) -> None:
        """Forget the commands taken: a step has used them."""
        self.pending.clear()
