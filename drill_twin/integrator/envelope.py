"""
What the string can plausibly do: scales derived from the configuration, ROS-free.

The twin refuses commands the model cannot represent (the command door,
:mod:`drill_twin.twin.commands`) and checks every step against physics (:mod:`.guard`) with
the same numbers, all derived here from the model as built (the string's weight, mass, drag
and geometry), never from our own output:

- **String weight** W = H_S - f_c: the hook load that balances the whole string with the bit
  just touching the rock (WOB = 0), as the model counts it (steel and fluid loads of the
  prestress, Eq. 29: the prestressed hook load H_S carries everything but the bit reaction
  f_c). The stationary WOB is f_c + (H - H_S) (docs/MODEL-CHOICES.md), so WOB = 0 at H = W.
- **Axial drag** C = e^T [C] e, e the rigid axial translation: the viscous force per m/s that
  resists the whole string moving axially (Rayleigh alpha (M + M_f), the fluid's damping).
  A hook load W + dH lifts the string (off bottom, or away from the rock in today's model)
  and it accelerates until the drag balances dH, at the terminal speed dH / C. The largest
  accepted hook load is W + C v_max: the string would never rise faster than
  PLAUSIBLE_BLOCK_SPEED_M_PER_S (a drawworks hoisting a stand). Anything more is refused:
  the model has no friction or block-travel limit, and 3 MN on this 1.16 MN string sent
  the bit 7 km up at 470 m/s.
- **Largest WOB**: the operating envelope's ENVELOPE_WEIGHT_ON_BIT_MAX_N, but at most the
  weight of the bottom-hole assembly (the sections below the lowest drill pipe), so that the
  neutral point stays in the BHA and the drill pipe in tension (the drilling engineer's
  rule); never less than the configuration's own static WOB |f_c|. The smallest accepted hook
  load is W - WOB_max.
- **Axial impedance** Z = A sqrt(E rho) of the bottom section: the force a landing at speed v
  puts on the bit is about Z v (a wave leaving the bit).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drill_twin.model.bit_rock import BitRockLaw

PLAUSIBLE_BLOCK_SPEED_M_PER_S = 1.0
"""Fastest plausible axial motion of the string (m/s): a drawworks hoists a stand at about
0.5 to 1.5 m/s; drilling (ROP) is a thousand times slower."""

ENVELOPE_WEIGHT_ON_BIT_MAX_N = 300.0e3
"""The operating envelope's largest weight on bit (N), docs/ENVELOPE.md."""

ENVELOPE_TOP_DRIVE_SPEED_MAX_RAD_PER_S = 30.0
"""The operating envelope's fastest top-drive speed (rad/s), docs/ENVELOPE.md."""


@dataclass(frozen=True)
class StringEnvelope:
    """
    Scales of the string as built (SI units; see the module docstring).

    string_weight_n: W, the hook load at WOB = 0 (N); string_mass_kg: the rigid axial mass
    e^T (M + M_f) e (kg); axial_drag_n_s_per_m: C; bha_weight_n: the BHA's weight (N; the
    whole string's when it has no BHA); weight_on_bit_max_n: the largest accepted WOB (N,
    positive); axial_impedance_n_s_per_m: Z of the bottom section; polar_inertia_kg_m2: the
    string's polar inertia psi^T (M + M_f) psi; hook_load_min_n, hook_load_max_n: the range of
    hook loads the model can represent (N).
    """

    string_weight_n: float
    string_mass_kg: float
    axial_drag_n_s_per_m: float
    bha_weight_n: float
    weight_on_bit_max_n: float
    axial_impedance_n_s_per_m: float
    polar_inertia_kg_m2: float

    @property
    def hook_load_min_n(self) -> float:
        return self.string_weight_n - self.weight_on_bit_max_n

    @property
    def hook_load_max_n(self) -> float:
        return self.string_weight_n + self.axial_drag_n_s_per_m * PLAUSIBLE_BLOCK_SPEED_M_PER_S

    def hook_load_reason(self, newton: float) -> str | None:
        """Why the model cannot represent the hook load ``newton`` (N), or None."""
        weight = self.string_weight_n
        if newton > self.hook_load_max_n:
            speed = (newton - weight) / self.axial_drag_n_s_per_m
            return (f'hook load command {_kn(newton)} exceeds the string\'s weight '
                    f'{_kn(weight)} by {_kn(newton - weight)}: it would lift the string at up to '
                    f'{speed:.3g} m/s against the drag of {self.axial_drag_n_s_per_m:.4g} N s/m, '
                    f'faster than a block moves ({PLAUSIBLE_BLOCK_SPEED_M_PER_S:g} m/s); the '
                    f'largest hook load accepted is {_kn(self.hook_load_max_n)}')
        if newton < self.hook_load_min_n:
            return (f'hook load command {_kn(newton)} would put {_kn(weight - newton)} on the '
                    f'bit, more than the largest weight on bit {_kn(self.weight_on_bit_max_n)} '
                    f'(the envelope\'s {_kn(ENVELOPE_WEIGHT_ON_BIT_MAX_N)}, at most the BHA\'s '
                    f'weight {_kn(self.bha_weight_n)}); the smallest hook load accepted is '
                    f'{_kn(self.hook_load_min_n)}')
        return None

    @classmethod
    def of(cls, system) -> 'StringEnvelope':
        """Build the envelope of a reduced system (:mod:`~drill_twin.model.reduced_system`)."""
        model = system.model
        mesh, prestress = model.mesh, model.prestress
        weight = prestress.hook_load_n - prestress.static_weight_on_bit_n
        translation = np.zeros(mesh.n_dofs)
        translation[0::6] = 1.0                              # u of every node (dofs.U = 0)
        mass = float(translation @ (model.total_mass @ translation))
        drag = float(translation @ (model.damping() @ translation))
        bha = _bha_weight(model, weight)
        wob_max = max(min(ENVELOPE_WEIGHT_ON_BIT_MAX_N, bha), -prestress.static_weight_on_bit_n)
        bottom = mesh.n_elements - 1
        impedance = float(mesh.area_m2[bottom]) * math.sqrt(
            mesh.young_modulus_pa[bottom] * mesh.density_kg_per_m3[bottom])
        driven = system.basis.driven_rotation
        inertia = float(driven @ (model.total_mass @ driven))
        return cls(string_weight_n=float(weight), string_mass_kg=mass,
                   axial_drag_n_s_per_m=max(drag, 1e-12), bha_weight_n=float(bha),
                   weight_on_bit_max_n=float(wob_max), axial_impedance_n_s_per_m=impedance,
                   polar_inertia_kg_m2=inertia)


def _kn(newton: float) -> str:
    return f'{newton / 1e3:.1f} kN'


def _bha_weight(model, weight_n: float) -> float:
    """
    Weight of the sections below the lowest drill pipe (N), as the model counts it.

    The axial force at the top of the BHA with the bit just touching (WOB = 0). The force N_0 =
    N_S - f_c is linear in each element (consistent loads) and exact at the midpoints; it is
    extrapolated to the top of the BHA from its two uppermost elements. A string whose bottom
    section is drill pipe has no BHA: the whole weight counts.
    """
    config, mesh = model.config, model.mesh
    kinds = [section.kind for section in config.sections]
    if kinds[-1] == 'drill_pipe' or 'drill_pipe' not in kinds:
        return float(weight_n)
    lowest_pipe = max(k for k, kind in enumerate(kinds) if kind == 'drill_pipe')
    elements = np.flatnonzero(mesh.section_index > lowest_pipe)
    force = model.prestress.axial_force_n - model.prestress.static_weight_on_bit_n
    middle = mesh.node_x_m[:-1] + 0.5 * mesh.length_m
    top = mesh.node_x_m[elements[0]]
    if elements.size == 1:                       # N_0 falls to 0 at the free bit end
        first = elements[0]
        bit = mesh.node_x_m[-1]
        return float(force[first] * (bit - top) / (bit - middle[first]))
    a, b = elements[0], elements[1]
    slope = (force[b] - force[a]) / (middle[b] - middle[a])
    return float(force[a] + slope * (top - middle[a]))


def largest_torque_on_bit_nm(law: BitRockLaw, top_speed_max_rad_per_s: float,
                             weight_on_bit_max_n: float, germs: np.ndarray | None = None):
    """
    Return the largest |TOB| of the bit-rock law over the envelope (N m).

    Bit speeds 0 ... the top speed, at the steady ROP of the largest WOB, the ROP capped at the
    block speed (a law whose ROP exceeds it is itself implausible and is caught on the ROP).
    With ``germs`` (m, 2, 2): the largest |TOB| of each member's random law at the same points
    (Eq. 50), shape (m,), never below the mean law's.
    """
    omega = np.linspace(0.01, max(top_speed_max_rad_per_s, 0.01), 400)
    rop = np.clip(law.steady_rop(omega, -weight_on_bit_max_n), 0.0,
                  PLAUSIBLE_BLOCK_SPEED_M_PER_S)
    force, torque = law.mean(rop, omega)
    mean = float(np.max(np.abs(torque)))
    if germs is None:
        return mean
    # The random torque of Eq. 50 is affine in (G22, G12) (G11 acts on the force only):
    # evaluated for three germs, it is had for any number of members by one product.
    basis = np.zeros((3, omega.size, 2, 2))
    basis[1, :, 1, 1] = 1.0
    basis[2, :, 0, 1] = basis[2, :, 1, 0] = 1.0
    at = [law.randomised(force, torque, rop, rop, omega, b)[1] for b in basis]
    germs = np.asarray(germs, dtype=float)
    random = (at[0] + np.outer(germs[:, 1, 1], at[1] - at[0])
              + np.outer(germs[:, 0, 1], at[2] - at[0]))
    return np.maximum(np.max(np.abs(random), axis=1), mean)
