"""
Contact events that mean something.

One impact per contact episode, one lift-off per separation of the bit from the rock
(docs/LATERAL.md, "Contact and lift-off episodes").

A node whirling along the wall, or grazing it, crosses r = c (c the clearance) back and forth
at every step; counting every onset (``Simulator.contact_onset_count``) counts that
chatter. Here an episode opens when the node first penetrates the wall (r - c > 0) and closes
only when it has come away from the wall by more than ``release_m`` (r - c < -release_m):
hysteresis in the radial gap. Each episode is one impact event, with the node's depth, the
time it opened and closed, and its peak radial force and penetration.

The bit likewise: a lift-off episode opens when the rock stops pushing on the bit (the
``lifted`` flag) and closes only once the rock pushes again with at least ``release_n``
(|f_bit| >= release_n): a bit that touches and leaves the rock within a fraction of its load
is one lift-off, not many.

The trackers are fed after every step (they keep per-member state); counts and rates over a
window are the KPIs. The :class:`~drill_twin.integrator.simulator.Simulator` feeds one of each
(``Simulator.impact_count`` and ``lift_off_count`` are their counts) from the contact flags
and forces of its step (:meth:`ContactEpisodes.update_from_contact`: the gap is computed only
at the nodes of open episodes that no longer touch).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

IMPACT_RELEASE_M = 1.0e-3
"""Default hysteresis of a wall-contact episode: 1 mm of gap (the penetrations of the
paper's k_ip = 1e8 N/m are below 1 mm for forces below 100 kN)."""
LIFT_OFF_RELEASE_N = 1.0e3
"""Default reload that ends a lift-off episode: 1 kN, 1 % of the paper's weight on bit."""


def radial_gap_m(system, displacement: np.ndarray) -> np.ndarray:
    """
    Return r - c at every node, (m, n_nodes) (m): > 0 inside the wall (penetration).

    displacement: field-wise DOFs from the prestress, (m, n_dofs).
    """
    v = displacement[:, system.field(2)]
    w = displacement[:, system.field(4)]
    return np.hypot(v, w) - system.clearance_m


def node_gap_m(system, q: np.ndarray, members: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Return r - c of k (member, node) pairs from the reduced coordinates q (m, n), (k,) (m)."""
    y, z = system.blocks['bending_y'], system.blocks['bending_z']
    rows = q[members]
    v = np.einsum('kj,kj->k', y.shapes[nodes], rows[:, y.columns])
    w = np.einsum('kj,kj->k', z.shapes[nodes], rows[:, z.columns])
    return np.hypot(v, w) - system.clearance_m[nodes]


@dataclass
class ImpactEvent:
    """
    One contact episode of one node with the wall.

    member, node: which; depth_m: x of the node (m, down from the top); start_s, end_s: when it
    opened and closed (end_s None while open); peak_force_n: largest radial force (N);
    peak_penetration_m: largest r - c (m).
    """

    member: int
    node: int
    depth_m: float
    start_s: float
    end_s: float | None = None
    peak_force_n: float = 0.0
    peak_penetration_m: float = 0.0


@dataclass
class ContactEpisodes:
    """
    Wall-contact episodes of m members over n nodes (see the module docstring).

    node_depth_m: (n_nodes,); release_m: the gap hysteresis (m, >= 0). ``opened`` and
    ``closed`` hold the events of the last update; ``history`` every closed event (unless
    keep_history is False: a long run's tracker keeps only counts and open episodes);
    ``count`` (m,) episodes opened since the start.
    """

    members: int
    node_depth_m: np.ndarray
    release_m: float = IMPACT_RELEASE_M
    keep_history: bool = True
    count: np.ndarray = field(init=False)
    history: list = field(init=False, default_factory=list)
    opened: list = field(init=False, default_factory=list)
    closed: list = field(init=False, default_factory=list)

    def __post_init__(self):
        if not self.release_m >= 0:
            raise ValueError(f'release_m must be >= 0, got {self.release_m}')
        self.node_depth_m = np.asarray(self.node_depth_m, dtype=float)
        self.count = np.zeros(self.members, dtype=int)
        self._open: dict[tuple[int, int], ImpactEvent] = {}

    def prime(self, time_s: float, in_contact: np.ndarray) -> None:
        """Contact already there at the start (m, n_nodes): open episodes, not counted."""
        for member, node in zip(*np.nonzero(np.asarray(in_contact, dtype=bool))):
            self._open[(int(member), int(node))] = ImpactEvent(
                int(member), int(node), float(self.node_depth_m[node]), float(time_s))

    @property
    def open_events(self) -> list:
        """Episodes still in progress."""
        return list(self._open.values())

    @property
    def any_open(self) -> bool:
        """Whether an episode is in progress."""
        return bool(self._open)

    def update_untouched(self) -> None:
        """Feed a step in which no node touches the wall, with no episode open: nothing happens."""
        if self._open:
            raise ValueError('episodes are open: feed the step with update_from_contact')
        self.opened, self.closed = [], []

    def update(self, time_s: float, gap_m: np.ndarray, radial_force_n: np.ndarray) -> None:
        """Feed one step: gap r - c and radial wall force, both (m, n_nodes)."""
        gap = np.asarray(gap_m, dtype=float)
        self._advance(time_s, gap > 0.0, np.asarray(radial_force_n, dtype=float), gap,
                      lambda members, nodes: gap[members, nodes])

    def update_from_contact(self, time_s: float, in_contact: np.ndarray,
                            radial_force_n: np.ndarray, stiffness_n_per_m: float,
                            gap_of, any_touching: bool | None = None) -> None:
        """
        Feed one step from what the contact force saw.

        in_contact and the radial force F = k_ip (r - c), (m, n_nodes); ``gap_of(members,
        nodes)`` gives r - c of the pairs (k,) (m) whose episode is open and which no longer
        touch (called only for those). ``any_touching``: whether any flag of in_contact is
        set, when the caller knows (None: looked up).
        """
        touching = np.asarray(in_contact, dtype=bool)
        if not self._open and (any_touching is False or not touching.any()):
            self.opened, self.closed = [], []            # nothing touches, nothing open
            return
        force = np.asarray(radial_force_n, dtype=float)
        penetration = force / stiffness_n_per_m if stiffness_n_per_m > 0 else 0.0 * force
        self._advance(time_s, touching, force, penetration, gap_of)

    def _advance(self, time_s, touching, force, penetration, gap_of) -> None:
        """
        Open or extend the episodes of the touching pairs.

        Close the open ones that have come away from the wall by more than release_m.
        """
        self.opened, self.closed = [], []
        for member, node in zip(*np.nonzero(touching)):
            key = (int(member), int(node))
            event = self._open.get(key)
            if event is None:
                event = ImpactEvent(key[0], key[1], float(self.node_depth_m[node]),
                                    float(time_s))
                self._open[key] = event
                self.opened.append(event)
                self.count[member] += 1
            event.peak_force_n = max(event.peak_force_n, float(force[member, node]))
            event.peak_penetration_m = max(event.peak_penetration_m,
                                           float(penetration[member, node]))
        waiting = [key for key in self._open if not touching[key]]
        if not waiting:
            return
        members, nodes = (np.array(index, dtype=int) for index in zip(*waiting))
        for key, gap in zip(waiting, np.asarray(gap_of(members, nodes), dtype=float)):
            if gap < -self.release_m:
                event = self._open.pop(key)
                event.end_s = float(time_s)
                self.closed.append(event)
                if self.keep_history:
                    self.history.append(event)


@dataclass
class LiftOffEpisodes:
    """
    Lift-off episodes of the bit of m members (see the module docstring).

    release_n: the compressive bit force (N, >= 0) that ends an episode. ``count`` (m,):
    episodes opened since the start; ``lifted`` (m,): an episode is in progress; ``opened``
    (m,) bool: opened at the last update.
    """

    members: int
    release_n: float = LIFT_OFF_RELEASE_N
    count: np.ndarray = field(init=False)
    lifted: np.ndarray = field(init=False)
    opened: np.ndarray = field(init=False)

    def __post_init__(self):
        if not self.release_n >= 0:
            raise ValueError(f'release_n must be >= 0, got {self.release_n}')
        self.count = np.zeros(self.members, dtype=int)
        self.lifted = np.zeros(self.members, dtype=bool)
        self.opened = np.zeros(self.members, dtype=bool)
        self._any = False                   # an episode in progress or opened at the last update

    def prime(self, lifted: np.ndarray) -> None:
        """
        Prime the tracker with the bits already off the rock at the start, (m,).

        Such a bit is an episode in progress, not counted.
        """
        self.lifted = np.array(lifted, dtype=bool)
        self._any = bool(self.lifted.any() or self.opened.any())

    def update(self, lifted: np.ndarray, weight_on_bit_n: np.ndarray,
               lifted_count: int | None = None) -> None:
        """
        Feed one step: the bit's lifted flag and f_bit (N, < 0 in compression), (m,).

        ``lifted_count``: how many flags are set, when the caller knows (None: counted here).
        """
        if not self._any and not (np.count_nonzero(lifted) if lifted_count is None
                                  else lifted_count):         # on the rock before and now
            return
        lifted = np.asarray(lifted, dtype=bool)
        if not (lifted.any() or self.lifted.any()):
            self.opened = np.zeros(self.members, dtype=bool)
            self._any = False
            return
        reloaded = ~lifted & (-np.asarray(weight_on_bit_n, dtype=float) >= self.release_n)
        self.opened = lifted & ~self.lifted
        self.count += self.opened
        self.lifted = (self.lifted | lifted) & ~reloaded
        self._any = bool(self.lifted.any() or self.opened.any())


def event_rate_per_s(count_at_start, count_at_end, window_s: float) -> np.ndarray:
    """Events per second in a window from two running counts (m,)."""
    if not window_s > 0:
        raise ValueError(f'window_s must be > 0, got {window_s}')
    return (np.asarray(count_at_end, dtype=float) - np.asarray(count_at_start)) / window_s
