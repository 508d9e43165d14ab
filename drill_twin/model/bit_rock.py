"""
The bit-rock interaction law (Eq. 24-26) and its random counterpart (Eq. 42-50).

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

from dataclasses import dataclass, replace

import numpy as np

from drill_twin.config.schema import BitRock
from drill_twin.numerics.compiled import inline, kernel

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
    compliance: float = 0.0
    """1 / k of the rock under the bit (m/N); 0: a rigid rock (``bit_equation``)."""

    @classmethod
    def from_config(cls, bit_rock: BitRock) -> 'BitRockLaw':
        stiffness = bit_rock.contact_stiffness_n_per_m
        return cls(a1=bit_rock.a1_m_per_s, a2=bit_rock.a2_m_per_n_s, a3=bit_rock.a3_m_per_rad,
                   a4=bit_rock.a4_n_rad, a5=bit_rock.a5_n_m, e=bit_rock.regularization_rad_per_s,
                   rop_scale=bit_rock.random_law_rop_scale_m_per_s,
                   compliance=0.0 if stiffness is None else 1.0 / stiffness)

    @property
    def constants(self) -> np.ndarray:
        """(a1, a2, a3, a4, a5, e, r, 1/k): the law's constants as the kernels take them."""
        return np.array([self.a1, self.a2, self.a3, self.a4, self.a5, self.e, self.rop_scale,
                         self.compliance])

    def rows(self, scales: np.ndarray | None = None) -> np.ndarray:
        """
        Return the kernels' constants per member, (m, 8), or (1, 8) for one law.

        ``scales``: (m, 5) factors of a1 ... a5 per member (an ensemble filter estimates
        them), or None. e, r and 1/k are the batch's.
        """
        if scales is None:
            return self.constants[None]
        scales = np.asarray(scales, dtype=float)
        if scales.ndim != 2 or scales.shape[1] != 5:
            raise ValueError(f'law scales must have shape (m, 5), got {scales.shape}')
        rows = np.repeat(self.constants[None], scales.shape[0], axis=0)
        rows[:, :5] *= scales
        return rows

    def scaled(self, scales) -> 'BitRockLaw':
        """Return this law with a1 ... a5 multiplied by ``scales`` (5,)."""
        a = np.asarray(scales, dtype=float) * self.constants[:5]
        return replace(self, a1=float(a[0]), a2=float(a[1]), a3=float(a[2]), a4=float(a[3]),
                       a5=float(a[4]))

    def mean(self, rop, omega):
        """
        Return (f_bit, t_bit) of the regularised law, without the lift-off cut.

        Any shape; complex arguments for complex-step differentiation.
        """
        force, torque, _, _ = _call_law(self, rop, omega, None, cut=False)
        return force, torque

    def forces(self, rop, omega, germ=None):
        """
        (f_bit, t_bit, lifted): the law with lift-off, randomised by ``germ`` if given.

        rop, omega: shape (m,) (real, or complex for complex-step derivatives); germ:
        (m, 2, 2) or None. Returns arrays of shape (m,).
        """
        force, torque, lifted, _ = _call_law(self, rop, omega, germ)
        return force, torque, lifted

    def forces_and_jacobian(self, rop, omega, germ=None, scales=None):
        """
        (f, t, lifted, J) with J[m] = d(f, t)/d(ROP, omega), shape (m, 2, 2) (analytic).

        ``scales``: (m, 5) factors of a1 ... a5 per member (:meth:`rows`), or None.
        """
        return _call_law(self, np.asarray(rop, dtype=float), np.asarray(omega, dtype=float),
                         germ, scales=scales)

    # -- the law as the bit's solve uses it: ROP and torque as functions of the force ------
    # Views over arrays of the compiled scalar law (:func:`cutting_rate`, :func:`fade_force`,
    # :func:`torque_of_force`, :func:`randomised_point`): one implementation, any broadcast
    # shape of real arguments.
    def cutting_rate(self, force, omega):
        """
        R(f, omega) = Z^2 (-a1 - a2 f) + a3 omega Z (m/s).

        The rate the bit cuts at under the mean-law force f (N, < 0 pushes), Eq. 25 solved for
        ROP; negative below the cutting threshold. Smooth in f and omega, also at omega = 0 (R ~
        omega^2), and even in omega as the regularised law is (docs/MODEL-CHOICES.md, backward
        rotation).
        """
        return self._graph(force, omega)[0]

    def threshold_force(self, omega):
        """
        Return the f at which R(f, omega) = 0 (N).

        For omega > 0, (a3 sqrt(omega^2 + e^2) - a1) / a2 (N), written for any omega (even);
        about -47 kN at 5.2 rad/s, > 0 above 24.9 rad/s.
        """
        return self._graph(0.0, omega)[2]

    def fade_force(self, omega):
        """
        f_ref = min(threshold, -TORQUE_FADE_FORCE_N) (N).

        The torque fades in proportion to the force between f_ref and lift-off (f = 0), see
        ``torque_of_force``.
        """
        return self._graph(0.0, omega)[3]

    @property
    def fade_speed_rad_per_s(self) -> float:
        """
        Bit speed above which the threshold force exceeds -TORQUE_FADE_FORCE_N (rad/s).

        Below it, the torque fade never acts on the cutting branch (inf if it never does).
        """
        return float(fade_speeds(self.constants[None])[0])

    def torque_of_force(self, force, omega, cutting_rate=None):
        """
        t_bit on bottom under the mean-law force f (N m).

        The torque is

            t = -Z (a4 max(R, 0) / sqrt(omega^2 + e^2) + a5) min(1, f / f_ref),

        which is Eq. 26, t = -a4 ROP omega / s - a5 Z, wherever the bit cuts with f <= f_ref
        (the whole cutting branch below 24.8 rad/s). Below the cutting threshold (the bit
        rests on the rock, ROP = 0) the friction-like term -a5 Z is carried in proportion to
        the force and vanishes at lift-off, so the torque is continuous in f everywhere.
        ``cutting_rate``: R(f, omega) if known (else computed).
        """
        return self._graph(force, omega, cutting_rate)[1]

    def bearing_torque(self, force, omega, germ=None, scales=None):
        """
        Torque on bit (N m) where the rock bears the axial force ``force`` (m,) <= 0 (N).

        The point of the law's graph with that force at ``omega`` (m,) rad/s, as the bit's
        solve has it (:func:`bearing_torques`): what a compliant rock's spring force implies
        for the torque, on the cutting and the resting branch alike. germ (m, 2, 2) or None;
        scales (m, 5) factors of a1 ... a5 or None.
        """
        force = np.ascontiguousarray(force, dtype=float)
        omega = np.ascontiguousarray(np.broadcast_to(omega, force.shape), dtype=float)
        torque = np.empty(force.shape)
        bearing_torques(force, omega, _germ_rows(germ), germ is not None, self.rows(scales),
                        torque)
        return torque

    def randomised(self, force, torque, rop, cutting_rate, omega, germ):
        """
        (F1, F2) of the random law at a point of the law's graph (shapes (m,)).

        force, torque: the mean law there; rop: the bit's ROP (>= cutting rate on bottom);
        cutting_rate: R(f, omega). The deviation of Eq. 50, written with A = diag(-f/ROP,
        -t/omega), is blended in with w(max(R, 0)) (w(ROP) on the cutting branch, as in
        ``forces``; 0 where the bit does not cut, so the law is continuous at omega = 0 and
        at the cutting threshold). The axial force cannot pull (F1 <= 0); the torque is
        kept when the random F1 reaches 0, so it stays continuous (docs/MODEL-CHOICES.md).
        germ: (m or 1, 2, 2), or None (the mean law: force and torque as given).
        """
        if germ is None:
            return force, torque
        shape, flat = _flattened(force, torque, rop, cutting_rate, omega)
        out = np.empty((2, flat[0].size))
        randomised_points(*flat, _germ_rows(germ), self.rows(), out)
        return tuple(row.reshape(shape)[()] for row in out)

    def steady_rop(self, omega, force_n):
        """
        ROP of Eq. 24 (regularised) at a bit speed and a bit force f (N, < 0 pushes) (m/s).

        Steady drilling: the cutting rate :meth:`cutting_rate` at (f, omega).
        """
        return self.cutting_rate(force_n, omega)

    def steady_torque(self, omega, force_n):
        """Torque on bit of the regularised law at steady drilling under the bit force f (N m)."""
        return self.mean(self.steady_rop(omega, force_n), omega)[1]

    def _graph(self, force, omega, rate=None):
        """(R, t_bit, threshold, f_ref) of :func:`graph_points` at broadcast force, omega."""
        given = rate is not None
        shape, flat = _flattened(force, omega, rate if given else 0.0)
        out = np.empty((4, flat[0].size))
        graph_points(*flat, given, self.rows(), out)
        return tuple(row.reshape(shape)[()] for row in out)


def fade_speeds(rows: np.ndarray) -> np.ndarray:
    """:attr:`BitRockLaw.fade_speed_rad_per_s` of each row of constants (m, 8), (m,) rad/s."""
    a1, a2, a3, e = rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 5]
    with np.errstate(divide='ignore', invalid='ignore'):
        root = (a1 - a2 * TORQUE_FADE_FORCE_N) / a3
        speed = np.sqrt(np.maximum(root * root - e * e, 0.0))
    return np.where(a3 <= 0, np.inf, np.where(root > 0, speed, 0.0))


# -- the compiled law ----------------------------------------------------------------------
# One scalar implementation, for float and complex arguments (complex-step derivatives):
# comparisons read the real parts. The constants k are BitRockLaw.constants.

_IDENTITY_GERM = np.eye(2)[None]


@inline
def away_from_zero(omega):
    """Return omega with its real part at least OMEGA_FLOOR in magnitude (imaginary untouched)."""
    real = omega.real
    if abs(real) < OMEGA_FLOOR_RAD_PER_S:
        floored = -OMEGA_FLOOR_RAD_PER_S if real < 0 else OMEGA_FLOOR_RAD_PER_S
        return floored + (omega - real)
    return omega


@inline
def law_point(rop, omega, g11, g12, g22, random, k):
    """
    (f, t, J00, J01, J10, J11) of the law at one (ROP, omega), before the lift-off cut.

    Eq. 25-26 and, with ``random``, the blended random law on C (module docstring) with its
    Jacobian by the chain rule.
    """
    a1, a2, a3, a4, a5, e, scale = k[0], k[1], k[2], k[3], k[4], k[5], k[6]
    e2 = e * e
    w = away_from_zero(omega)
    s = omega * omega + e2
    root = np.sqrt(s)
    slope_ratio = (w * w + e2) / (w * w)                        # 1 / Z^2
    force = -rop * slope_ratio / a2 + a3 * root / a2 - a1 / a2
    torque = -a4 * rop * omega / s - a5 * omega / root
    j00 = -slope_ratio / a2
    j01 = 2 * rop * e2 / (a2 * (w * w * w)) + a3 * omega / (a2 * root)
    j10 = -a4 * omega / s
    j11 = -a4 * rop * (e2 - omega * omega) / (s * s) - a5 * e2 / (s * root)
    if not (random and rop.real > 0 and omega.real > 0 and force.real < 0
            and torque.real < 0):
        return force, torque, j00, j01, j10, j11
    r, v = rop, omega
    p = force * torque
    dp0 = j00 * torque + force * j10
    dp1 = j01 * torque + force * j11
    q1, q2 = p * v / r, p * r / v
    dq10 = dp0 * (v / r) - p * v / (r * r)
    dq11 = dp1 * (v / r) + p / r
    dq20 = dp0 * (r / v) + p / v
    dq21 = dp1 * (r / v) - p * r / (v * v)
    r1, r2 = np.sqrt(q1), np.sqrt(q2)
    deviation0 = (g11 - 1) * force - g12 * r1
    deviation1 = (g22 - 1) * torque - g12 * r2
    d00 = (g11 - 1) * j00 - g12 * dq10 / (2 * r1)
    d01 = (g11 - 1) * j01 - g12 * dq11 / (2 * r1)
    d10 = (g22 - 1) * j10 - g12 * dq20 / (2 * r2)
    d11 = (g22 - 1) * j11 - g12 * dq21 / (2 * r2)
    square = r * r                                              # the blend w(ROP), dw/dROP
    denominator = square + scale * scale
    weight = square / denominator
    d_weight = 2 * r * scale * scale / (denominator * denominator)
    return (force + weight * deviation0, torque + weight * deviation1,
            j00 + weight * d00 + deviation0 * d_weight, j01 + weight * d01,
            j10 + weight * d10 + deviation1 * d_weight, j11 + weight * d11)


@inline
def z_factor(omega, k):
    """Z = omega / sqrt(omega^2 + e^2) of Eq. 25 (scalar)."""
    return omega / np.sqrt(omega * omega + k[5] * k[5])


@inline
def cutting_rate(force, omega, k):
    """R(f, omega) of :meth:`BitRockLaw.cutting_rate` (scalars)."""
    z = z_factor(omega, k)
    return z * z * (-k[0] - k[1] * force) + k[2] * omega * z


@inline
def threshold_force(omega, k):
    """Return the force f of :meth:`BitRockLaw.threshold_force` (scalar, N)."""
    return (k[2] * np.sqrt(omega * omega + k[5] * k[5]) - k[0]) / k[1]


@inline
def fade_force(omega, k):
    """f_ref of :meth:`BitRockLaw.fade_force` (scalar)."""
    return minimum(threshold_force(omega, k), -TORQUE_FADE_FORCE_N)


@inline
def torque_of_force(force, omega, rate, k):
    """t_bit of :meth:`BitRockLaw.torque_of_force` (scalars; ``rate`` = R(f, omega))."""
    root = np.sqrt(omega * omega + k[5] * k[5])
    share = force / fade_force(omega, k)
    if share < 0.0:
        share = 0.0
    elif share > 1.0:
        share = 1.0
    return -(omega / root) * (k[3] * maximum(rate, 0.0) / root + k[4]) * share


@inline
def randomised_point(force, torque, rop, rate, omega, g11, g12, g22, random, k):
    """(F1, F2) of :meth:`BitRockLaw.randomised` at one point of the law's graph."""
    if not random:
        return force, torque
    if rate > 0 and rop > 0 and omega > 0 and force < 0 and torque < 0:
        coupling = np.sqrt((force / rop) * (torque / omega))
        weight = rate * rate / (rate * rate + k[6] * k[6])
        f1 = force + weight * ((g11 - 1.0) * force - g12 * coupling * omega)
        f2 = torque + weight * ((g22 - 1.0) * torque - g12 * coupling * rop)
    else:
        weight = 0.0 / (k[6] * k[6])
        f1 = force + weight * ((g11 - 1.0) * force)
        f2 = torque + weight * ((g22 - 1.0) * torque)
    return minimum(f1, 0.0), f2


@inline
def minimum(a, b):
    """np.minimum of two scalars (nan propagates)."""
    return a if a != a or a < b else b


@inline
def maximum(a, b):
    """np.maximum of two scalars (nan propagates)."""
    return a if a != a or a > b else b


@kernel
def bit_law(rop, omega, germ, random, constants, cut, force, torque, lifted, jacobian):
    """
    Evaluate the law at every (rop[i], omega[i]) (m,).

    Into force, torque, lifted (m,) and jacobian (m, 2, 2); germ (m or 1, 2, 2) is used when
    ``random``; constants (m or 1, 8): the law's (:meth:`BitRockLaw.rows`); ``cut``: the
    lift-off cut (f >= 0: all zero and lifted), else the raw law (lifted False).
    """
    last = germ.shape[0] - 1
    last_law = constants.shape[0] - 1
    for i in range(rop.shape[0]):
        g = min(i, last)
        f, t, j00, j01, j10, j11 = law_point(rop[i], omega[i], germ[g, 0, 0], germ[g, 0, 1],
                                             germ[g, 1, 1], random,
                                             constants[min(i, last_law)])
        off = cut and f.real >= 0.0
        lifted[i] = off
        if off:
            f = t = j00 = j01 = j10 = j11 = 0.0 * f
        force[i] = f
        torque[i] = t
        jacobian[i, 0, 0] = j00
        jacobian[i, 0, 1] = j01
        jacobian[i, 1, 0] = j10
        jacobian[i, 1, 1] = j11


@kernel
def graph_points(force, omega, rate, given, constants, out):
    """
    Evaluate the law's graph at every (force[i], omega[i]) (m,) for :class:`BitRockLaw`'s views.

    Into out (4, m): R(f, omega) (or ``rate`` (m,) where ``given``), t_bit of
    :func:`torque_of_force` at that rate, the threshold force and f_ref at omega. constants
    (m or 1, 8) as bit_law's.
    """
    last_law = constants.shape[0] - 1
    for i in range(force.shape[0]):
        k = constants[min(i, last_law)]
        f, w = force[i], omega[i]
        cut = rate[i] if given else cutting_rate(f, w, k)
        out[0, i] = cut
        out[1, i] = torque_of_force(f, w, cut, k)
        out[2, i] = threshold_force(w, k)
        out[3, i] = fade_force(w, k)


@kernel
def randomised_points(force, torque, rop, rate, omega, germ, constants, out):
    """
    :func:`randomised_point` at every point (m,) into out (2, m): (F1, F2).

    germ (m or 1, 2, 2), constants (m or 1, 8) as bit_law's.
    """
    last = germ.shape[0] - 1
    last_law = constants.shape[0] - 1
    for i in range(force.shape[0]):
        g = germ[min(i, last)]
        out[0, i], out[1, i] = randomised_point(force[i], torque[i], rop[i], rate[i], omega[i],
                                                g[0, 0], g[0, 1], g[1, 1], True,
                                                constants[min(i, last_law)])


BEARING_ITERATIONS = 200
"""Cap of the bisection that finds the mean-law force of a borne force (~60 are used)."""


@kernel
def bearing_torques(force, omega, germ, random, constants, torque):
    """
    Torque on bit where the rock bears the axial force ``force`` (m,) <= 0 at ``omega`` (m,).

    Into ``torque`` (m,). The bit's solve (bit_equation) walks its graph along the mean-law
    force f: the rock's axial force is the random law's F1 at the law's own point (R(f, omega),
    omega) of f, its torque F2 likewise (on the cutting branch and on a compliant rock's
    resting branch alike). Here f is found back from F1: f = F1 for the mean law; with a germ
    by bisection on F1(f) = F1 over [lo, 0] (F1 is continuous, F1(0) = 0, F1 ~ G11 f for large
    |f|); where a germ with a large G12 makes F1(f) non-monotone, one of its roots. A force
    >= 0 (lifted) has no torque. germ (m or 1, 2, 2), constants (m or 1, 8) as bit_law's.
    """
    last = germ.shape[0] - 1
    last_law = constants.shape[0] - 1
    for i in range(force.shape[0]):
        g = germ[min(i, last)]
        k = constants[min(i, last_law)]
        target, w = force[i], omega[i]
        if not target < 0.0:
            torque[i] = 0.0
            continue
        if not random:
            torque[i] = torque_of_force(target, w, cutting_rate(target, w, k), k)
            continue
        low, high = target, 0.0
        for _ in range(BEARING_ITERATIONS):
            if _borne(low, w, g[0, 0], g[0, 1], g[1, 1], k)[0] <= target:
                break
            high, low = low, 2.0 * low
        for _ in range(BEARING_ITERATIONS):
            middle = 0.5 * (low + high)
            if middle <= low or middle >= high:
                break
            if _borne(middle, w, g[0, 0], g[0, 1], g[1, 1], k)[0] <= target:
                low = middle
            else:
                high = middle
        torque[i] = _borne(0.5 * (low + high), w, g[0, 0], g[0, 1], g[1, 1], k)[1]


@inline
def _borne(mean_force, omega, g11, g12, g22, k):
    """(F1, F2) of the random law at the law's own point of the mean-law force (scalars)."""
    cut = cutting_rate(mean_force, omega, k)
    mean_torque = torque_of_force(mean_force, omega, cut, k)
    return randomised_point(mean_force, mean_torque, cut, cut, omega, g11, g12, g22, True, k)


def _call_law(law: BitRockLaw, rop, omega, germ, cut: bool = True, scales=None):
    """bit_law on arrays of any (broadcast) shape; (f, t, lifted, J)."""
    dtype = np.result_type(rop, omega, float)
    shape, (flat_rop, flat_omega) = _flattened(rop, omega, dtype=dtype)
    size = flat_rop.size
    force, torque = np.empty(size, dtype), np.empty(size, dtype)
    lifted = np.empty(size, dtype=bool)
    jacobian = np.empty((size, 2, 2), dtype)
    bit_law(flat_rop, flat_omega, _germ_rows(germ), germ is not None, law.rows(scales), cut,
            force, torque, lifted, jacobian)
    return (force.reshape(shape)[()], torque.reshape(shape)[()], lifted.reshape(shape)[()],
            jacobian.reshape(shape + (2, 2)))


def _flattened(*values, dtype=float):
    """(shape, flat contiguous copies (size,)) of ``values`` broadcast together."""
    arrays = np.broadcast_arrays(*(np.asarray(value, dtype=dtype) for value in values))
    return arrays[0].shape, [np.ascontiguousarray(array).reshape(-1) for array in arrays]


def _germ_rows(germ) -> np.ndarray:
    """Germs (m or 1, 2, 2) as the kernels take them; the identity for None (mean law)."""
    if germ is None:
        return _IDENTITY_GERM
    return np.ascontiguousarray(germ, dtype=float).reshape(-1, 2, 2)
