"""
The rig's drives attached to a simulator (issue 13, docs/DRIVES.md).

``attach_drives(simulator)`` puts in place what ``simulator.config`` asks for: the dynamic
top drive (``top_drive.mode: dynamic``) and the drawworks (``drawworks.mode``
``block_velocity`` or ``autodriller``). Both act through the simulator's public commands: the
top drive stands in for ``simulator.top_drive`` (``advance(command, dt)`` returns the top
speed of the coming step), and the drawworks sets the hook load of the coming step
(``set_hook_load``) from the same call, which the simulator makes once at the start of every
step. With the defaults (kinematic drive, hook-load input) nothing changes.
"""
from __future__ import annotations

import copy
import dataclasses

from drill_twin.rig.drawworks import Drawworks
from drill_twin.rig.top_drive import attach_top_drive


class DriveTrain:
    """
    The simulator's ``top_drive`` when a drawworks is attached.

    Before each step the drawworks sets the hook load, then the top drive (kinematic or dynamic)
    advances. ``speed_rad_per_s`` set back after a failed step also puts the drawworks back.
    """

    def __init__(self, top_drive, drawworks: Drawworks):
        self.top_drive = top_drive
        self.drawworks = drawworks
        self._undo = None

    @property
    def speed_rad_per_s(self) -> float:
        return self.top_drive.speed_rad_per_s

    @speed_rad_per_s.setter
    def speed_rad_per_s(self, value: float) -> None:
        if self._undo is not None and value == self._undo[0]:
            self.drawworks.__dict__.update(self._undo[1])
        self._undo = None
        self.top_drive.speed_rad_per_s = value

    def after_reset(self) -> None:
        """Reseat the block: the simulator restarted members from a safe state."""
        self.drawworks.reseat()

    def advance(self, command_rad_per_s: float, dt: float) -> float:
        self._undo = (self.top_drive.speed_rad_per_s, copy.copy(self.drawworks.__dict__))
        self.drawworks.before_step()
        return self.top_drive.advance(command_rad_per_s, dt)


def attach_drives(simulator) -> None:
    """
    Attach the configured drives to ``simulator`` (module docstring).

    A second call changes nothing.
    """
    attach_top_drive(simulator)
    if (simulator.config.drawworks.mode != 'hook_load'
            and not isinstance(simulator.top_drive, DriveTrain)):
        simulator.top_drive = DriveTrain(simulator.top_drive,
                                         Drawworks(simulator, simulator.config.drawworks))


def drawworks_of(simulator) -> Drawworks | None:
    """Return the simulator's drawworks, or None (hook-load input)."""
    train = simulator.top_drive
    return train.drawworks if isinstance(train, DriveTrain) else None


def top_drive_of(simulator):
    """
    Return the simulator's top drive (kinematic or dynamic).

    It is found under a drawworks if there is one.
    """
    train = simulator.top_drive
    return train.top_drive if isinstance(train, DriveTrain) else train


def set_axial_mode(simulator, mode: str) -> None:
    """
    Switch the axial input at run time.

    'hook_load' (the hook load command stays what the line last pulled), 'block_velocity' or
    'autodriller' (the block starts where the line pulls the current hook load); bumpless either
    way.
    """
    drawworks = drawworks_of(simulator)
    if mode == 'hook_load':
        if drawworks is not None:
            simulator.top_drive = simulator.top_drive.top_drive
        return
    if drawworks is None:
        drawworks = Drawworks(simulator, simulator.config.drawworks)
        simulator.top_drive = DriveTrain(simulator.top_drive, drawworks)
    drawworks.set_mode(mode)


def _replace_top_drive(simulator, new_drive) -> None:
    train = simulator.top_drive
    if isinstance(train, DriveTrain):
        train.top_drive = new_drive
    else:
        simulator.top_drive = new_drive


def set_top_drive_mode(simulator, mode: str, controller: str | None = None) -> None:
    """
    Switch the top drive at run time, bumpless.

    'kinematic' (the speed now held, then following commands at
    ``operation.top_drive_acceleration_rad_per_s2``) or 'dynamic' (the PI integral starts at the
    string's current torque), with ``controller`` (stiff, soft_torque, impedance; None: the
    configured one).
    """
    from drill_twin.rig.controllers import make_controller
    from drill_twin.integrator.simulator import TopDrive
    from drill_twin.rig.top_drive import DynamicTopDrive

    if mode not in ('kinematic', 'dynamic'):
        raise ValueError(f'top drive mode must be kinematic or dynamic, not {mode!r}')
    speed = top_drive_of(simulator).speed_rad_per_s
    settings = simulator.config.top_drive
    settings = dataclasses.replace(settings, mode=mode,
                                   controller=controller or settings.controller)
    config = dataclasses.replace(simulator.config, top_drive=settings)
    if mode == 'kinematic':
        drive = TopDrive(speed, config.operation.top_drive_acceleration_rad_per_s2)
    else:
        drive = DynamicTopDrive(simulator, settings, make_controller(config, simulator.system))
    _replace_top_drive(simulator, drive)


def set_torque_limit(simulator, newton_metre: float) -> None:
    """Set the dynamic drive's motor torque limit (N m, > 0), from the next step on."""
    drive = top_drive_of(simulator)
    if not hasattr(drive, 'loop'):
        raise ValueError('the torque limit applies to the dynamic top drive only')
    if not newton_metre > 0:
        raise ValueError(f'the torque limit must be > 0 N m, got {newton_metre!r}')
    drive.loop.limit = float(newton_metre)
