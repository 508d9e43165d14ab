"""
The analysed state of a batch of members, read from and written back into a Simulator.

Per member the state vector is, in order: the reduced coordinates q of the analysed blocks,
their rates, the hole's offset below the bit (m, >= 0 off bottom; on bottom 0, or minus the
depth by which the bit presses a compliant rock) and, with parameters
'germ', the bit-rock germ's three Cholesky coordinates (log L11, L12, log L22) with
[G_b] = L^T L, L upper triangular (any value is a symmetric positive-definite germ).

Writing back (:meth:`MemberState.write`) is an adapter over the Simulator's public state
(``state``, ``integrator``): the new coordinates, the accelerations that balance them
(``NewmarkIntegrator.initial_state``), the germ, and the forces re-evaluated. The
Simulator has no setter for a batch state; this is the one place that does it.
"""
from __future__ import annotations

import numpy as np

from drill_twin.dynamics.simulator import Simulator

GERM_COORDINATES = ('log_l11', 'l12', 'log_l22')
GERM_DIAGONAL_LIMIT = 100.0
"""An analysed member's germ keeps L11^2 and L22^2 within [1/limit, limit] and |L12| within
sqrt(limit): the prior at the largest dispersion the twin accepts (0.65) stays inside (20 000
draws: L^2 within 0.012 ... 5). Without a bound the filter can drive a poorly observed
entry towards a germ near singular (its coordinates then lose their meaning to rounding)."""
_LOG_DIAGONAL_LIMIT = 0.5 * np.log(GERM_DIAGONAL_LIMIT)


def germ_to_coordinates(germ: np.ndarray) -> np.ndarray:
    """
    (m, 2, 2) SPD germs -> (m, 3) coordinates (log L11, L12, log L22), G = L^T L.

    For a germ near singular, G22 - L12^2 is floored at 1e-12 G22 (rounding can make it
    negative).
    """
    g11, g12, g22 = germ[:, 0, 0], germ[:, 0, 1], germ[:, 1, 1]
    l11 = np.sqrt(g11)
    l12 = g12 / l11
    l22 = np.sqrt(np.maximum(g22 - l12 * l12, 1e-12 * g22))
    return np.stack([np.log(l11), l12, np.log(l22)], axis=1)


def bounded_coordinates(coordinates: np.ndarray) -> np.ndarray:
    """Return germ coordinates (m, 3) within :data:`GERM_DIAGONAL_LIMIT`'s bounds."""
    limit = _LOG_DIAGONAL_LIMIT
    bound = np.sqrt(GERM_DIAGONAL_LIMIT)
    return np.stack([np.clip(coordinates[:, 0], -limit, limit),
                     np.clip(coordinates[:, 1], -bound, bound),
                     np.clip(coordinates[:, 2], -limit, limit)], axis=1)


def coordinates_to_germ(coordinates: np.ndarray) -> np.ndarray:
    """(m, 3) coordinates -> (m, 2, 2) symmetric positive-definite germs."""
    l11, l12, l22 = np.exp(coordinates[:, 0]), coordinates[:, 1], np.exp(coordinates[:, 2])
    germ = np.empty((coordinates.shape[0], 2, 2))
    germ[:, 0, 0] = l11 * l11
    germ[:, 0, 1] = germ[:, 1, 0] = l11 * l12
    germ[:, 1, 1] = l12 * l12 + l22 * l22
    return germ


class MemberState:
    """
    The analysed state of members 0..members-1 of ``simulator`` (the rest untouched).

    :param simulator: the batch (its integrator must carry germs when parameters='germ').
    :param members: how many of its first members are analysed.
    :param blocks: names of the reduced-coordinate blocks analysed ('axial', 'torsional', ...).
    :param parameters: 'germ' or 'none'.
    """

    def __init__(self, simulator: Simulator, members: int, blocks, parameters: str = 'germ'):
        self.simulator = simulator
        self.members = int(members)
        system = simulator.system
        self.columns = np.concatenate([np.arange(system.size)[system.blocks[b].columns]
                                       for b in blocks])
        self.parameters = parameters
        if parameters == 'germ' and simulator.integrator.germ is None:
            raise ValueError("parameters 'germ' needs a simulator with germs")
        axial = system.blocks['axial']
        self._bit_row = np.zeros(system.size)
        self._bit_row[axial.columns] = axial.shapes[system.bit_node]

    @property
    def size(self) -> int:
        """Length of a member's state vector."""
        return 2 * self.columns.size + 1 + (3 if self.parameters == 'germ' else 0)

    def extract(self) -> np.ndarray:
        """Return the state vectors, shape (members, size)."""
        state, m = self.simulator.state, self.members
        q, rate = state.q[:m], state.q_rate[:m]
        offset = self.simulator.hole_u()[:m] - q @ self._bit_row
        parts = [q[:, self.columns], rate[:, self.columns], offset[:, None]]
        if self.parameters == 'germ':
            parts.append(germ_to_coordinates(self.simulator.integrator.germ[:m]))
        return np.concatenate(parts, axis=1)

    def bit_speed_direction(self) -> np.ndarray:
        """
        Return the least-norm change of a state vector that raises the bit's speed, (size,).

        The change raises the bit's speed (relative to the top) by 1 rad/s: along the
        torsional shapes at the bit, in the rates. Requires the torsional block among the
        analysed ones.
        """
        system = self.simulator.system
        torsion = system.blocks['torsional']
        row = np.zeros(system.size)
        row[torsion.columns] = torsion.shapes[system.bit_node]
        shapes = row[self.columns]
        if not np.any(shapes):
            raise ValueError('the torsional block is not analysed')
        direction = np.zeros(self.size)
        k = self.columns.size
        direction[k:2 * k] = shapes / (shapes @ shapes)
        return direction

    def germs(self) -> np.ndarray:
        """Return the analysed members' germs, (members, 2, 2)."""
        return self.simulator.integrator.germ[:self.members].copy()

    def write(self, vectors: np.ndarray) -> None:
        """
        Put state vectors (members, size) back.

        A member on bottom before stays on bottom (pressing a compliant rock as deep as before,
        the force's change acting from the next step); an analysed offset is never negative; a
        germ is kept within :data:`GERM_DIAGONAL_LIMIT`'s bounds. Raises ValueError for a
        non-finite vector (nothing is written).
        """
        sim, m, k = self.simulator, self.members, self.columns.size
        vectors = np.asarray(vectors, dtype=float)
        if vectors.shape != (m, self.size):
            raise ValueError(f'state vectors must have shape ({m}, {self.size})')
        if not np.all(np.isfinite(vectors)):
            raise ValueError('the analysed state is not finite')
        state = sim.state
        was_on_bottom = sim.on_bottom()[:m]
        q, rate = state.q[:m].copy(), state.q_rate[:m].copy()
        q[:, self.columns] = vectors[:, :k]
        rate[:, self.columns] = vectors[:, k:2 * k]
        pressed = np.minimum(sim.hole_u()[:m] - state.q[:m] @ self._bit_row, 0.0)
        offset = np.where(was_on_bottom, pressed, np.maximum(vectors[:, 2 * k], 0.0))
        germs = (coordinates_to_germ(bounded_coordinates(vectors[:, 2 * k + 1:2 * k + 4]))
                 if self.parameters == 'germ' else None)
        sim.set_members(q, rate, q @ self._bit_row + offset, germs)
