"""The random germ [G_b] of Appendix B and the per-realization random streams."""
import math

import numpy as np
import pytest
from numpy.testing import assert_array_equal
from scipy import special

from drill_twin.uncertainty.germ import (
    GERM_ORDER, MAX_DISPERSION, dispersion_of, germs_for_realizations, realization_generator,
    sample_germ)

N_DRAWS = 200_000
Z_TOLERANCE = 5.0  # standard errors; a fixed seed makes each check deterministic anyway


@pytest.fixture
def rng():
    return np.random.default_rng(20090601)


def test_bound_is_sqrt_three_sevenths():
    assert GERM_ORDER == 2
    assert MAX_DISPERSION == pytest.approx(math.sqrt(3.0 / 7.0))


@pytest.mark.parametrize('delta', [0.001, 0.01, 0.1, 0.3])
def test_mean_is_identity(delta, rng):
    germs = sample_germ(delta, rng, N_DRAWS)
    # Wishart moments: Var G_jj = 2 delta^2 / (n+1), Var G_12 = delta^2 / (n+1).
    standard_error = delta * np.sqrt(np.array([[2.0, 1.0], [1.0, 2.0]]) / (3.0 * N_DRAWS))
    deviation = np.abs(germs.mean(axis=0) - np.eye(2))
    assert np.all(deviation < Z_TOLERANCE * standard_error)


@pytest.mark.parametrize('delta', [0.001, 0.01, 0.1, 0.3])
def test_dispersion_matches(delta, rng):
    germs = sample_germ(delta, rng, N_DRAWS)
    # mean of q = ||G - I||^2 / 2 estimates delta^2 without bias; its standard error
    # is estimated from the draws themselves.
    q = 0.5 * np.sum((germs - np.eye(2))**2, axis=(1, 2))
    standard_error = q.std(ddof=1) / np.sqrt(N_DRAWS)
    assert abs(dispersion_of(germs)**2 - delta**2) < Z_TOLERANCE * standard_error
    assert dispersion_of(germs) == pytest.approx(delta, rel=0.01)


@pytest.mark.parametrize('delta', [0.1, 0.5])
def test_log_determinant_matches_wishart(delta, rng):
    """E{log det G} = n log(2 sigma^2) + sum_j psi(shape_j): checks the Gamma shapes."""
    germs = sample_germ(delta, rng, N_DRAWS)
    shapes = 3.0 / (2.0 * delta**2) + (1.0 - np.arange(1, 3)) / 2.0
    expected = 2.0 * np.log(2.0 * delta**2 / 3.0) + special.digamma(shapes).sum()
    log_det = np.linalg.slogdet(germs)[1]
    standard_error = log_det.std(ddof=1) / np.sqrt(N_DRAWS)
    assert abs(log_det.mean() - expected) < Z_TOLERANCE * standard_error


@pytest.mark.parametrize('delta', [0.001, 0.3, 0.65, 0.999 * MAX_DISPERSION])
def test_every_draw_symmetric_positive_definite(delta, rng):
    germs = sample_germ(delta, rng, N_DRAWS)
    assert germs.shape == (N_DRAWS, 2, 2)
    assert_array_equal(germs, np.swapaxes(germs, 1, 2))
    assert np.all(np.linalg.eigvalsh(germs) > 0.0)


def test_zero_dispersion_is_identity_and_draws_nothing(rng):
    state = rng.bit_generator.state
    assert_array_equal(sample_germ(0.0, rng, 5), np.broadcast_to(np.eye(2), (5, 2, 2)))
    assert rng.bit_generator.state == state
    assert_array_equal(germs_for_realizations(0.0, 3, [0, 1]), np.stack([np.eye(2)] * 2))


def test_empty_draw(rng):
    assert sample_germ(0.1, rng, 0).shape == (0, 2, 2)


@pytest.mark.parametrize('delta', [-1e-9, MAX_DISPERSION, 0.7, 1.0, np.inf, np.nan])
def test_invalid_dispersion_raises(delta, rng):
    with pytest.raises(ValueError, match='dispersion'):
        sample_germ(delta, rng, 1)
    with pytest.raises(ValueError, match='dispersion'):
        germs_for_realizations(delta, 0, [0])


def test_negative_seed_or_index_raises():
    with pytest.raises(ValueError):
        realization_generator(-1, 0)
    with pytest.raises(ValueError):
        realization_generator(0, -1)


def test_realizations_independent_of_batching_and_order():
    delta, seed = 0.1, 4242
    at_once = germs_for_realizations(delta, seed, range(100))
    order = np.random.default_rng(7).permutation(100)
    in_batches = np.empty_like(at_once)
    for start in range(0, 100, 7):
        batch = order[start:start + 7]
        in_batches[batch] = germs_for_realizations(delta, seed, batch)
    assert_array_equal(in_batches, at_once)
    assert np.unique(at_once[:, 0, 0]).size == 100


def test_realization_stream_is_spawned_child():
    children = np.random.SeedSequence(11).spawn(5)
    expected = np.random.Generator(np.random.PCG64(children[3])).random(4)
    assert_array_equal(realization_generator(11, 3).random(4), expected)


def test_seeds_give_different_germs():
    first = germs_for_realizations(0.1, 1, range(10))
    second = germs_for_realizations(0.1, 2, range(10))
    assert not np.any(np.isclose(first[:, 0, 0], second[:, 0, 0], rtol=0.0, atol=1e-15))


def test_dispersion_of_constructed_samples():
    samples = np.stack([np.eye(2) + [[0.3, 0.0], [0.0, 0.0]],
                        np.eye(2) - [[0.0, 0.1], [0.1, 0.0]]])
    # ||.||_F^2: 0.09 and 0.02; delta^2 = (0.09 + 0.02) / 2 / 2
    assert dispersion_of(samples) == pytest.approx(math.sqrt(0.11 / 4.0))
