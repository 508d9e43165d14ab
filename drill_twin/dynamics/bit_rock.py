"""The bit-rock interaction law (Eq. 24-26) and its random counterpart (Eq. 42-50).

With the bit velocities x = (ROP, omega) = (du_bit/dt, dtheta_bit/dt), Z = omega / sqrt(omega^2
+ e^2) and s = omega^2 + e^2, the regularised law of Eq. 25 reads

    f_bit = -ROP s / (a2 omega^2) + a3 sqrt(s) / a2 - a1 / a2
    t_bit = -a4 ROP omega / s - a5 omega / sqrt(s)

(forces the rock applies to the bit; f_bit < 0 is compression). When the law would pull on the
rock (f_bit >= 0) the bit has lifted off and both vanish (MODEL.md).

Random law. [A_b(x)] = diag(-f/ROP, -t/omega) is positive-definite on its admissible set
C = {ROP > 0, omega > 0, f < 0, t < 0}; with L_b = sqrt([A_b]) and a germ [G_b],
F = -L_b^T G_b L_b x (Eq. 50) becomes

    F_1 = G11 f - G12 sqrt(f t omega / ROP),    F_2 = G22 t - G12 sqrt(f t ROP / omega).

Outside C the factorisation does not exist and the mean law is used. Inside C, the term
G12 sqrt(f t omega / ROP) is about G12 x 1 MN at the operating point and grows without bound
as ROP -> 0+, while the mean law holds about -47 kN there: the random force would jump
from -infinity to the mean law at ROP = 0, and for some germs at delta = 0.1 it cannot balance
the weight at any ROP > 0. The random deviation is therefore blended into the mean law near
that boundary, F = f + w (F_random - f) with w = ROP^2 / (ROP^2 + r^2), r =
``random_law_rop_scale_m_per_s`` (default 1e-4 m/s: at the nominal 2.6 mm/s, w = 0.9985).
The law is then continuous, and smooth but for the lift-off cut (docs/MODEL-CHOICES.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drill_twin.config.schema import BitRock

OMEGA_FLOOR_RAD_PER_S = 1e-9
"""|omega| is kept above this in 1 / omega^2 (the law is singular at omega = 0)."""
TORQUE_FADE_FORCE_N = 1e3
"""Above 24.8 rad/s the cutting threshold is above -1 kN: there the torque fades to zero
over the last TORQUE_FADE_FORCE_N of force before lift-off (``torque_of_force``)."""


@dataclass(frozen=True)
class BitRockLaw:
    """Eq. 25-26 with the paper's constants (SI units)."""

    a1: float
    a2: float
    a3: float
    a4: float
    a5: float
    e: float
    rop_scale: float = 1e-4
    """r of the blend of the random law into the mean law near ROP = 0 (m/s)."""

    @classmethod
    def from_config(cls, bit_rock: BitRock) -> 'BitRockLaw':
        return cls(a1=bit_rock.a1_m_per_s, a2=bit_rock.a2_m_per_n_s, a3=bit_rock.a3_m_per_rad,
                   a4=bit_rock.a4_n_rad, a5=bit_rock.a5_n_m, e=bit_rock.regularization_rad_per_s,
                   rop_scale=bit_rock.random_law_rop_scale_m_per_s)

    def mean(self, rop, omega):
        """(f_bit, t_bit) of the regularised law, without the lift-off cut (any shape)."""
        omega_safe = _away_from_zero(omega)
        s = omega * omega + self.e * self.e
        root = np.sqrt(s)
        force = (-rop * (omega_safe * omega_safe + self.e * self.e)
                 / (self.a2 * omega_safe * omega_safe)
                 + self.a3 * root / self.a2 - self.a1 / self.a2)
        torque = -self.a4 * rop * omega / s - self.a5 * omega / root
        return force, torque

    def forces(self, rop, omega, germ=None):
        """(f_bit, t_bit, lifted): the law with lift-off, randomised by ``germ`` if given.

        rop, omega: shape (m,); germ: (m, 2, 2) or None. Returns arrays of shape (m,).
        """
        force, torque = self.mean(rop, omega)
        if germ is not None:
            force, torque = _randomise(force, torque, rop, omega, germ, self.rop_scale)
        lifted = np.real(force) >= 0.0
        zero = np.zeros_like(force)
        return np.where(lifted, zero, force), np.where(lifted, zero, torque), lifted

    def forces_and_jacobian(self, rop, omega, germ=None):
        """(f, t, lifted, J) with J[m] = d(f, t)/d(ROP, omega), shape (m, 2, 2) (analytic)."""
        rop = np.asarray(rop, dtype=float)
        omega = np.asarray(omega, dtype=float)
        e2 = self.e * self.e
        w = _away_from_zero(omega)
        s = omega * omega + e2
        root = np.sqrt(s)
        slope_ratio = (w * w + e2) / (w * w)                    # 1 / Z^2
        force = -rop * slope_ratio / self.a2 + self.a3 * root / self.a2 - self.a1 / self.a2
        torque = -self.a4 * rop * omega / s - self.a5 * omega / root
        jacobian = np.empty(rop.shape + (2, 2))
        jacobian[..., 0, 0] = -slope_ratio / self.a2
        jacobian[..., 0, 1] = 2 * rop * e2 / (self.a2 * w ** 3) + self.a3 * omega / (self.a2 * root)
        jacobian[..., 1, 0] = -self.a4 * omega / s
        jacobian[..., 1, 1] = (-self.a4 * rop * (e2 - omega * omega) / (s * s)
                               - self.a5 * e2 / (s * root))
        if germ is not None:
            force, torque, jacobian = _randomise_with_jacobian(force, torque, jacobian, rop,
                                                               omega, germ, self.rop_scale)
        lifted = force >= 0.0
        force = np.where(lifted, 0.0, force)
        torque = np.where(lifted, 0.0, torque)
        jacobian = np.where(lifted[..., None, None], 0.0, jacobian)
        return force, torque, lifted, jacobian

    # -- the law as the bit's solve uses it: ROP and torque as functions of the force ------
    def cutting_rate(self, force, omega):
        """R(f, omega) = Z^2 (-a1 - a2 f) + a3 omega Z (m/s): the rate the bit cuts at under the
        mean-law force f (N, < 0 pushes), Eq. 25 solved for ROP; negative below the cutting
        threshold. Smooth in f and omega, also at omega = 0 (R ~ omega^2), and even in omega
        as the regularised law is (docs/MODEL-CHOICES.md, backward rotation)."""
        z = self._cutting_z(omega)
        return z * z * (-self.a1 - self.a2 * force) + self.a3 * omega * z

    def threshold_force(self, omega):
        """f at which R(f, omega) = 0 for omega > 0, (a3 sqrt(omega^2 + e^2) - a1) / a2 (N),
        written for any omega (even); about -47 kN at 5.2 rad/s, > 0 above 24.9 rad/s."""
        return (self.a3 * np.sqrt(omega * omega + self.e * self.e) - self.a1) / self.a2

    def fade_force(self, omega):
        """f_ref = min(threshold, -TORQUE_FADE_FORCE_N) (N): the torque fades in proportion
        to the force between f_ref and lift-off (f = 0), see ``torque_of_force``."""
        return np.minimum(self.threshold_force(omega), -TORQUE_FADE_FORCE_N)

    @property
    def fade_speed_rad_per_s(self) -> float:
        """Bit speed above which the threshold force exceeds -TORQUE_FADE_FORCE_N (rad/s):
        below it, the torque fade never acts on the cutting branch (inf if it never does)."""
        if self.a3 <= 0:
            return float('inf')
        root = (self.a1 - self.a2 * TORQUE_FADE_FORCE_N) / self.a3
        return float(np.sqrt(max(root * root - self.e * self.e, 0.0))) if root > 0 else 0.0

    def torque_of_force(self, force, omega, cutting_rate=None):
        """t_bit on bottom under the mean-law force f (N m):

            t = -Z (a4 max(R, 0) / sqrt(omega^2 + e^2) + a5) min(1, f / f_ref),

        which is Eq. 26, t = -a4 ROP omega / s - a5 Z, wherever the bit cuts with f <= f_ref
        (the whole cutting branch below 24.8 rad/s). Below the cutting threshold (the bit
        rests on the rock, ROP = 0) the friction-like term -a5 Z is carried in proportion to
        the force and vanishes at lift-off, so the torque is continuous in f everywhere."""
        s = omega * omega + self.e * self.e
        root = np.sqrt(s)
        rate = self.cutting_rate(force, omega) if cutting_rate is None else cutting_rate
        share = np.clip(force / self.fade_force(omega), 0.0, 1.0)
        return -(omega / root) * (self.a4 * np.maximum(rate, 0.0) / root + self.a5) * share

    def randomised(self, force, torque, rop, cutting_rate, omega, germ):
        """(F1, F2) of the random law at a point of the law's graph (shapes (m,)).

        force, torque: the mean law there; rop: the bit's ROP (>= cutting rate on bottom);
        cutting_rate: R(f, omega). The deviation of Eq. 50, written with A = diag(-f/ROP,
        -t/omega), is blended in with w(max(R, 0)) (w(ROP) on the cutting branch, as in
        ``forces``; 0 where the bit does not cut, so the law is continuous at omega = 0 and
        at the cutting threshold). The axial force cannot pull (F1 <= 0); the torque is
        kept when the random F1 reaches 0, so it stays continuous (docs/MODEL-CHOICES.md).
        """
        if germ is None:
            return force, torque
        g11, g12, g22 = germ[:, 0, 0], germ[:, 0, 1], germ[:, 1, 1]
        admissible = (cutting_rate > 0) & (rop > 0) & (omega > 0) & (force < 0) & (torque < 0)
        safe_rop = np.where(admissible, rop, 1.0)
        safe_omega = np.where(admissible, omega, 1.0)
        coupling = np.sqrt(np.where(admissible, (force / safe_rop) * (torque / safe_omega), 0.0))
        cut = np.where(admissible, cutting_rate, 0.0)
        weight = cut * cut / (cut * cut + self.rop_scale * self.rop_scale)
        f1 = force + weight * ((g11 - 1.0) * force - g12 * coupling * safe_omega)
        f2 = torque + weight * ((g22 - 1.0) * torque - g12 * coupling * safe_rop)
        return np.minimum(f1, 0.0), f2

    def _cutting_z(self, omega):
        return omega / np.sqrt(omega * omega + self.e * self.e)

    def steady_rop(self, omega, weight_on_bit_n):
        """ROP of Eq. 24 (regularised) at a given bit speed and weight on bit."""
        z = omega / np.sqrt(omega * omega + self.e * self.e)
        return z * z * (-self.a1 - self.a2 * weight_on_bit_n) + self.a3 * omega * z

    def steady_torque(self, omega, weight_on_bit_n):
        """Torque on bit of the regularised law at a steady (ROP, omega)."""
        return self.mean(self.steady_rop(omega, weight_on_bit_n), omega)[1]


def _away_from_zero(omega):
    """omega with its real part kept at least OMEGA_FLOOR in magnitude (imaginary part, used
    by complex-step differentiation, untouched)."""
    real = np.real(omega)
    floored = np.where(real < 0, -OMEGA_FLOOR_RAD_PER_S, OMEGA_FLOOR_RAD_PER_S)
    return np.where(np.abs(real) < OMEGA_FLOOR_RAD_PER_S, floored + (omega - real), omega)


def _blend(rop, scale):
    """w = ROP^2 / (ROP^2 + r^2) and dw/dROP."""
    square = rop * rop
    denominator = square + scale * scale
    return square / denominator, 2 * rop * scale * scale / (denominator * denominator)


def _randomise_with_jacobian(force, torque, jacobian, rop, omega, germ, scale):
    """The (blended) random law on C and its Jacobian by the chain rule (mean law outside C)."""
    g11, g12, g22 = germ[:, 0, 0], germ[:, 0, 1], germ[:, 1, 1]
    admissible = (rop > 0) & (omega > 0) & (force < 0) & (torque < 0)
    r = np.where(admissible, rop, 1.0)
    w = np.where(admissible, omega, 1.0)
    p = np.where(admissible, force * torque, 1.0)
    dp = jacobian[..., 0, :] * torque[..., None] + force[..., None] * jacobian[..., 1, :]
    q1, q2 = p * w / r, p * r / w
    dq1 = dp * (w / r)[..., None] + np.stack([-p * w / r ** 2, p / r], axis=-1)
    dq2 = dp * (r / w)[..., None] + np.stack([p / w, -p * r / w ** 2], axis=-1)
    r1, r2 = np.sqrt(q1), np.sqrt(q2)
    deviation = np.stack([(g11 - 1) * force - g12 * r1, (g22 - 1) * torque - g12 * r2], axis=-1)
    d_deviation = np.empty_like(jacobian)
    d_deviation[..., 0, :] = ((g11 - 1)[..., None] * jacobian[..., 0, :]
                              - g12[..., None] * dq1 / (2 * r1[..., None]))
    d_deviation[..., 1, :] = ((g22 - 1)[..., None] * jacobian[..., 1, :]
                              - g12[..., None] * dq2 / (2 * r2[..., None]))
    weight, d_weight = _blend(r, scale)
    random_jacobian = jacobian + weight[..., None, None] * d_deviation
    random_jacobian[..., :, 0] += deviation * d_weight[..., None]
    keep = admissible[..., None, None]
    return (np.where(admissible, force + weight * deviation[..., 0], force),
            np.where(admissible, torque + weight * deviation[..., 1], torque),
            np.where(keep, random_jacobian, jacobian))


def _randomise(force, torque, rop, omega, germ, scale):
    """The (blended) random law written directly (works for complex arguments)."""
    g11, g12, g22 = germ[:, 0, 0], germ[:, 0, 1], germ[:, 1, 1]
    admissible = ((np.real(rop) > 0) & (np.real(omega) > 0) & (np.real(force) < 0)
                  & (np.real(torque) < 0))
    safe_rop = np.where(admissible, rop, 1.0)
    safe_omega = np.where(admissible, omega, 1.0)
    product = np.where(admissible, force * torque, 1.0)
    random_force = g11 * force - g12 * np.sqrt(product * safe_omega / safe_rop)
    random_torque = g22 * torque - g12 * np.sqrt(product * safe_rop / safe_omega)
    weight = safe_rop * safe_rop / (safe_rop * safe_rop + scale * scale)
    return (np.where(admissible, force + weight * (random_force - force), force),
            np.where(admissible, torque + weight * (random_torque - torque), torque))
