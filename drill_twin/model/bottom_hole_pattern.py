"""
The lobed hole bottom under the bit (``excitation.bottom_hole_pattern``).

A roller-cone bit cuts a bottom with lobes (three for a tricone): as the bit turns, the rock
under it rises and falls, and the bit must follow. Drilling-vibration models impose it as a
surface under the bit (Spanos, Chevallier & Politis 2003; Yigit & Christoforou 2006):

    s(phi) = A sin(n phi),    ds/dt = A n omega cos(n phi),

phi the bit's spin angle (top-drive angle plus the bit's twist, as the imbalance's), omega
its spin rate, n the lobes, A the amplitude (m); s > 0 puts the undeformed rock below the
hole's mean bottom u_hole. The bit-rock graph of :mod:`bit_equation` then holds in the
surface's frame: the law sets the bit's axial velocity relative to the surface,
ROP_bit - ds/dt = R(f, omega) while it cuts; it rests on the rock's spring, pressed by
u_bit - (u_hole + s), and is free above it. The hole state ``hole_u`` stays the mean bottom
(it deepens at the relative ROP, the rate a driller measures); the lobes ride on it.

In a Newmark iteration s and kappa = A n cos(n phi) (ds/dt = kappa omega) are taken at the
iterate's angle and held while the 2x2 bit equation is solved, in which the surface's velocity
kappa omega moves with the bit's speed (the Newton step's Jacobian and the bracketed solve
have it: held at the iterate's speed instead, it fed the bit's speed back through the law's
steep torque near ROP = 0 and stalled steps of random germs in a 2-cycle).
"""
from __future__ import annotations

import numpy as np

from drill_twin.numerics.compiled import inline

ON, LOBES, AMPLITUDE = 0, 0, 1


def _arguments(on: bool, lobes: float, amplitude_m: float, torsion_row: int) -> tuple:
    return (bool(on), np.array([float(lobes), float(amplitude_m)]), np.zeros(1),
            np.array([int(torsion_row)], dtype=np.int64))


@inline
def surface(pattern, angle):
    """
    Return (s, kappa) of the surface at spin angle ``angle`` (rad): ds/dt = kappa omega.

    s (m) = A sin(n phi), kappa (m/rad) = A n cos(n phi); (0, 0) when the pattern is off.
    """
    if not pattern[0]:
        return 0.0, 0.0
    lobes, amplitude = pattern[1][LOBES], pattern[1][AMPLITUDE]
    phase = lobes * angle
    return amplitude * np.sin(phase), amplitude * lobes * np.cos(phase)


@inline
def surface_at(pattern, displacement_t, i):
    """Return (s, kappa) of member i, its bit's twist read in displacement_t (n_dofs, m)."""
    if not pattern[0]:
        return 0.0, 0.0
    return surface(pattern, pattern[2][0] + displacement_t[pattern[3][0], i])


class LobedBottom:
    """
    The lobed hole bottom of a system's bit (None from :meth:`of` when it is off).

    Attributes: lobes (n), amplitude_m (A, m), torsion_row (the field-wise DOF of the bit's
    twist).
    """

    def __init__(self, lobes: int, amplitude_m: float, torsion_row: int):
        self.lobes = int(lobes)
        self.amplitude_m = float(amplitude_m)
        self.torsion_row = int(torsion_row)
        self._arguments = _arguments(True, lobes, amplitude_m, torsion_row)

    @staticmethod
    def of(system) -> 'LobedBottom | None':
        """Return the pattern of ``system``'s configuration, or None when it is off."""
        pattern = system.model.config.excitation.bottom_hole_pattern
        if not pattern.enabled:
            return None
        return LobedBottom(pattern.lobes, pattern.amplitude_m,
                           system.field(1).start + system.bit_node)

    @staticmethod
    def arguments_of(pattern: 'LobedBottom | None') -> tuple:
        """Return the kernels' operands of ``pattern``, or an inert tuple of the same types."""
        return pattern.arguments() if pattern is not None else _arguments(False, 0, 0.0, 0)

    def arguments(self) -> tuple:
        """Return (on, (n, A) (2,), top-drive angle (1,) (rad, state), torsion row (1,))."""
        return self._arguments

    def set_top_angle(self, angle_rad: float) -> None:
        """Set the top-drive angle (rad) the next step adds to the bit's twist."""
        self._arguments[2][0] = angle_rad

    def height_m(self, angle_rad) -> np.ndarray:
        """Return s(phi), the undeformed rock below the mean bottom at the bit's angle (m)."""
        return self.amplitude_m * np.sin(self.lobes * np.asarray(angle_rad, dtype=float))

    def height_rate_m_per_s(self, angle_rad, rate_rad_per_s) -> np.ndarray:
        """Return ds/dt at the bit's angle (rad) and spin rate (rad/s) (m/s)."""
        phase = self.lobes * np.asarray(angle_rad, dtype=float)
        return self.amplitude_m * self.lobes * np.asarray(rate_rad_per_s) * np.cos(phase)
