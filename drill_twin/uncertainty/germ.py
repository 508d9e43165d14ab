"""
The random germ [G_b] of the non-parametric bit-rock law (paper Sect. 3, Appendix B).

[G_b] is a random symmetric positive-definite 2 x 2 matrix with E{[G_b]} = [I] and
dispersion delta = (1/2 E{||[G_b] - [I]||_F^2})^(1/2) (Eq. 45), distributed with the
maximum-entropy density of Eq. 46 (Soize's ensemble SG+). It is drawn once per Monte
Carlo realization and multiplies the Cholesky factors of the mean bit-rock matrix
(Eq. 44, 50); it is dimensionless.

Generator (Appendix B, the Bartlett decomposition of a Wishart matrix), n = 2:

    [G_b] = [L_G]^T [L_G],  [L_G] upper triangular with independent entries,
    sigma = delta / sqrt(n + 1),
    j < j':  [L_G]_jj' = sigma V_jj',          V_jj' ~ N(0, 1),
    j = j':  [L_G]_jj  = sigma sqrt(2 V_j),    V_j ~ Gamma((n + 1)/(2 delta^2) + (1 - j)/2, 1),

with j = 1..n. Equivalently [G_b] is Wishart with nu = (n + 1)/delta^2 degrees of freedom
and scale matrix (delta^2/(n + 1)) [I].

Admissible dispersion, 0 <= delta < sqrt((n + 1)/(n + 5)) = sqrt(3/7) ~ 0.6547 for n = 2:

- The density of Eq. 46, det(G)^((n+1)(1-delta^2)/(2 delta^2)) exp(-(n+1)/(2 delta^2) tr G),
  is integrable iff the last Gamma shape is positive, (n + 1)/(2 delta^2) > (n - 1)/2,
  i.e. delta < sqrt((n + 1)/(n - 1)) (sqrt(3) for n = 2). With the measure of Soize
  (2^(n(n-1)/4) prod dG_jk) its normalization constant is
  C = (2 pi)^(-n(n-1)/4) ((n+1)/(2 delta^2))^(n(n+1)/(2 delta^2)) / prod_j Gamma(shape_j);
  for n = 2 the power is 3/delta^2 (checked by numerical quadrature; the text of Eq. 47
  we have prints 3/(2 delta^2)).
- The third piece of available information, E{||[G_b]^-1||_F^2} < +inf, needs more: for a
  Wishart matrix the second moments of the inverse exist iff nu > n + 3, i.e.
  delta < sqrt((n + 1)/(n + 3)) (sqrt(3/5) ~ 0.775 for n = 2).
- Soize (Probab. Eng. Mech. 15, 2000; Comput. Methods Appl. Mech. Eng. 194, 2005) gives
  the admissible range 0 < delta < sqrt((n + 1)/(n + 5)) (nu > n + 5), stricter than both
  conditions above; as we read it, it comes from his bound of E{||[G]^-1||^2} by a
  constant independent of n. It is the range nonparametric-method codes check, and the
  one enforced here.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

GERM_ORDER = 2
"""n, the dimension of [G_b] (axial and torsional bit velocities)."""

MAX_DISPERSION = math.sqrt((GERM_ORDER + 1) / (GERM_ORDER + 5))
"""Exclusive upper bound of delta, sqrt((n + 1)/(n + 5)) = sqrt(3/7) ~ 0.6547."""


def validate_dispersion(dispersion: float) -> float:
    """Return delta as a float, or raise ValueError unless 0 <= delta < MAX_DISPERSION."""
    delta = float(dispersion)
    if not 0.0 <= delta < MAX_DISPERSION:
        raise ValueError(
            f'germ dispersion must satisfy 0 <= delta < sqrt((n+1)/(n+5)) = '
            f'{MAX_DISPERSION:.6f} for n = {GERM_ORDER} (Soize 2000, 2005); got {dispersion!r}')
    return delta


def gamma_shapes(dispersion: float) -> np.ndarray:
    """
    Shapes (n + 1)/(2 delta^2) + (1 - j)/2, j = 1..n, of the diagonal Gamma draws.

    :param dispersion: delta, 0 < delta < MAX_DISPERSION.

    :return: Shape (n,) array.
    """
    j = np.arange(1, GERM_ORDER + 1)
    return (GERM_ORDER + 1) / (2.0 * dispersion**2) + (1.0 - j) / 2.0


def sample_germ(dispersion: float, rng: np.random.Generator, size: int) -> np.ndarray:
    """
    Draw `size` independent realizations of [G_b] with the Appendix B generator.

    The stream is consumed in a fixed order: the (size, n(n-1)/2) standard normals of the
    strictly upper part of [L_G] first, then the (size, n) Gamma variables of its diagonal.
    For delta = 0 nothing is drawn and the identity is returned exactly.

    :param dispersion: delta, dimensionless, 0 <= delta < MAX_DISPERSION.
    :param rng: the generator to draw from.
    :param size: number of realizations, >= 0.

    :return: Shape (size, 2, 2) array of symmetric positive-definite matrices.
    """
    delta = validate_dispersion(dispersion)
    size = int(size)
    if size < 0:
        raise ValueError(f'size must be >= 0; got {size}')
    n = GERM_ORDER
    if delta == 0.0:
        return np.broadcast_to(np.eye(n), (size, n, n)).copy()
    sigma = delta / math.sqrt(n + 1)
    upper_rows, upper_cols = np.triu_indices(n, k=1)
    normals = rng.standard_normal((size, upper_rows.size))
    gammas = rng.gamma(gamma_shapes(delta), 1.0, size=(size, n))
    factor = np.zeros((size, n, n))
    factor[:, upper_rows, upper_cols] = sigma * normals
    diagonal = np.arange(n)
    factor[:, diagonal, diagonal] = sigma * np.sqrt(2.0 * gammas)
    return np.swapaxes(factor, -1, -2) @ factor


def realization_generator(seed: int, index: int) -> np.random.Generator:
    """
    Return the random stream of realization `index` of a study seeded with `seed`.

    The stream is PCG64 seeded by numpy.random.SeedSequence(seed, spawn_key=(index,)),
    i.e. the `index`-th child of SeedSequence(seed).spawn(...). It depends only on
    (seed, index): realization k gets the same numbers whether the study is run at once,
    in batches, in any order, or spread over workers. Children of one seed are
    statistically independent streams.

    :param seed: the study's seed, a non-negative integer.
    :param index: the realization number, a non-negative integer.

    :return: A fresh Generator positioned at the start of the realization's stream.
    """
    seed, index = int(seed), int(index)
    if seed < 0 or index < 0:
        raise ValueError(f'seed and index must be non-negative; got seed={seed}, index={index}')
    sequence = np.random.SeedSequence(seed, spawn_key=(index,))
    return np.random.Generator(np.random.PCG64(sequence))


def germs_for_realizations(dispersion: float, seed: int, indices: Sequence[int]) -> np.ndarray:
    """
    Draw the germ of each listed realization, the first draw of its own stream.

    :param dispersion: delta, dimensionless, 0 <= delta < MAX_DISPERSION.
    :param seed: the study's seed (see realization_generator).
    :param indices: realization numbers, shape (n_realizations,).

    :return: Shape (n_realizations, 2, 2) array; row k is the germ of realization indices[k].
    """
    delta = validate_dispersion(dispersion)
    indices = np.asarray(indices, dtype=np.int64).reshape(-1)
    germs = np.empty((indices.size, GERM_ORDER, GERM_ORDER))
    for row, index in enumerate(indices):
        germs[row] = sample_germ(delta, realization_generator(seed, index), 1)[0]
    return germs


def dispersion_of(samples: np.ndarray) -> float:
    """
    Estimate delta = sqrt(1/n mean ||G - I||_F^2) of Eq. 45 (1/n = 1/2 for n = 2).

    :param samples: shape (n_samples, n, n).

    :return: The estimate of delta (its square is an unbiased estimate of delta^2).
    """
    samples = np.asarray(samples, dtype=float)
    n = samples.shape[-1]
    deviation = samples - np.eye(n)
    return float(np.sqrt(np.mean(np.sum(deviation**2, axis=(-2, -1))) / n))
