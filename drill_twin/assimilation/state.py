"""
The analysed state of a batch of members, read from and written back into a Simulator.

Per member the state vector is, in order: the reduced coordinates q of the analysed blocks,
their rates, the hole's offset below the bit (m, >= 0 off bottom; on bottom 0, or minus the
depth by which the bit presses a compliant rock) and, with parameters
'germ' or 'law', the bit-rock germ's three Cholesky coordinates (log L11, L12, log L22) with
[G_b] = L^T L, L upper triangular (any value is a symmetric positive-definite germ); with
'law' then the logarithms of the factors of the law's a1 ... a5 (any value is a law with
positive coefficients).

Writing back (:meth:`MemberState.write`) is an adapter over the Simulator's public state
(``state``, ``integrator``): the new coordinates, the accelerations that balance them
(``NewmarkIntegrator.initial_state``), the germ, and the forces re-evaluated. The
Simulator has no setter for a batch state; this is the one place that does it.
"""
from __future__ import annotations

import numpy as np

from drill_twin.integrator.simulator import Simulator

GERM_COORDINATES = ('log_l11', 'l12', 'log_l22')
LAW_COORDINATES = ('log_a1', 'log_a2', 'log_a3', 'log_a4', 'log_a5')
LAW_SCALE_LIMIT = 10.0
"""An analysed member's factors of a1 ... a5 stay within [1/limit, limit]."""
PARAMETER_COUNT = {'none': 0, 'germ': 3, 'law': 8}
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


def law_scales_for_members(log_std: float, seed: int, members: int) -> np.ndarray:
    """
    Return (members, 5) prior factors of a1 ... a5: exp of centred normals of ``log_std``.

    Drawn from ``numpy.random.default_rng(SeedSequence(seed, spawn_key=(2,)))`` (the germs and
    the filter's perturbations use other keys of the same seed).
    """
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(2,)))
    return np.exp(log_std * rng.standard_normal((members, 5)))


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
    :param parameters: 'germ', 'law' (the germ and the factors of a1 ... a5) or 'none'.
    """

    def __init__(self, simulator: Simulator, members: int, blocks, parameters: str = 'germ'):
        self.simulator = simulator
        self.members = int(members)
        system = simulator.system
        self.columns = np.concatenate([np.arange(system.size)[system.blocks[b].columns]
                                       for b in blocks])
        self.parameters = parameters
        if parameters not in PARAMETER_COUNT:
            raise ValueError(f'parameters must be one of {", ".join(PARAMETER_COUNT)}')
        if parameters != 'none' and simulator.integrator.germ is None:
            raise ValueError(f"parameters {parameters!r} needs a simulator with germs")
        axial = system.blocks['axial']
        self._bit_row = np.zeros(system.size)
        self._bit_row[axial.columns] = axial.shapes[system.bit_node]

    @property
    def parameter_count(self) -> int:
        """How many augmented parameters end a state vector (0, 3 or 8)."""
        return PARAMETER_COUNT[self.parameters]

    @property
    def size(self) -> int:
        """Length of a member's state vector."""
        return 2 * self.columns.size + 1 + PARAMETER_COUNT[self.parameters]

    def motion_columns(self) -> dict[str, np.ndarray]:
        """
        Return where each motion's numbers sit in a state vector: {'axial', 'torsional'}.

        'axial': the axial block's coordinates and rates and the hole's offset; 'torsional':
        the torsional block's coordinates and rates (either empty when its block is not
        analysed). The rest (bending blocks, parameters) is neither.
        """
        system, k = self.simulator.system, self.columns.size
        groups = {}
        for motion in ('axial', 'torsional'):
            mine = np.flatnonzero(np.isin(self.columns,
                                          np.arange(system.size)[system.blocks[motion].columns]))
            groups[motion] = np.concatenate([mine, k + mine])
        groups['axial'] = np.append(groups['axial'], 2 * k)
        return groups

    def extract(self) -> np.ndarray:
        """Return the state vectors, shape (members, size)."""
        state, m = self.simulator.state, self.members
        q, rate = state.q[:m], state.q_rate[:m]
        offset = self.simulator.hole_u()[:m] + self._lobes(q) - q @ self._bit_row
        parts = [q[:, self.columns], rate[:, self.columns], offset[:, None]]
        if self.parameters != 'none':
            parts.append(germ_to_coordinates(self.simulator.integrator.germ[:m]))
        if self.parameters == 'law':
            parts.append(np.log(self.law_scales()))
        return np.concatenate(parts, axis=1)

    def law_scales(self) -> np.ndarray:
        """Return the analysed members' factors of a1 ... a5, (members, 5) (1: the law's)."""
        scales = self.simulator.integrator.law_scales
        if scales is None:
            return np.ones((self.members, 5))
        return scales[:self.members].copy()

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
        germ is kept within :data:`GERM_DIAGONAL_LIMIT`'s bounds, a factor of the law within
        :data:`LAW_SCALE_LIMIT`'s. Raises ValueError for a
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
        pressed = np.minimum(sim.hole_u()[:m] + self._lobes(state.q[:m])
                             - state.q[:m] @ self._bit_row, 0.0)
        offset = np.where(was_on_bottom, pressed, np.maximum(vectors[:, 2 * k], 0.0))
        germs, scales = self.parameters_of(vectors)
        sim.set_members(q, rate, q @ self._bit_row + offset - self._lobes(q), germs, scales)

    def parameters_of(self, vectors: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
        """
        Return the germs (members, 2, 2) and law factors (members, 5) state vectors stand for.

        As :meth:`write` puts them (within their bounds); None where not estimated.
        """
        k = self.columns.size
        germs = (coordinates_to_germ(bounded_coordinates(vectors[:, 2 * k + 1:2 * k + 4]))
                 if self.parameters != 'none' else None)
        limit = np.log(LAW_SCALE_LIMIT)
        scales = (np.exp(np.clip(vectors[:, 2 * k + 4:2 * k + 9], -limit, limit))
                  if self.parameters == 'law' else None)
        return germs, scales

    def _lobes(self, q: np.ndarray):
        """
        Return the lobed bottom's height s under the bits of coordinates q (k, n) (m).

        The state's offset is the bit's distance to the rock surface under it, hole + s - u_bit
        (0 without a bottom-hole pattern).
        """
        integrator = self.simulator.integrator
        pattern = integrator.forces.bottom_pattern
        if pattern is None:
            return 0.0
        return pattern.height_m(integrator.bit_angle_rad(q, self.simulator.state.top_angle_rad))
