"""
The ensemble Kalman analysis against the Kalman filter, where the Kalman filter is exact.

The Kalman filter is exact for linear measurements of a Gaussian state.
"""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from drill_twin.assimilation.filter import analyse, inflation_transform, kalman_update


def _problem(rng, n=4, p=2):
    """Return a random Gaussian prior N(m, P), a linear operator H and noise R."""
    m = rng.normal(size=n)
    L = rng.normal(size=(n, n))
    P = L @ L.T + 0.5 * np.eye(n)
    H = rng.normal(size=(p, n))
    R = np.diag(rng.uniform(0.2, 1.0, size=p))
    y = H @ m + rng.normal(size=p)
    return m, P, H, R, y


def _sample(rng, mean, covariance, members):
    return rng.multivariate_normal(mean, covariance, size=members)


def test_etkf_is_the_kalman_filter_of_its_own_sample():
    """
    For a linear operator the ETKF's analysis equals the Kalman filter's.

    For a linear operator the ETKF's analysis mean and covariance are exactly the
    Kalman filter's applied to the forecast ensemble's sample mean and covariance.
    """
    rng = np.random.default_rng(1)
    m, P, H, R, y = _problem(rng)
    X = _sample(rng, m, P, 12)
    analysis = analyse(X @ H.T, y, R, method='etkf')
    Xa = analysis.apply(X)
    mean_kf, cov_kf = kalman_update(X.mean(0), np.cov(X.T), H, y, R)
    np.testing.assert_allclose(Xa.mean(0), mean_kf, rtol=0, atol=1e-10)
    np.testing.assert_allclose(np.cov(Xa.T), cov_kf, rtol=0, atol=1e-10)


def test_enkf_mean_is_the_kalman_mean_of_its_own_sample():
    """Centred perturbations: the stochastic EnKF's mean is the Kalman mean exactly."""
    rng = np.random.default_rng(2)
    m, P, H, R, y = _problem(rng)
    X = _sample(rng, m, P, 12)
    Xa = analyse(X @ H.T, y, R, method='enkf', rng=np.random.default_rng(3)).apply(X)
    mean_kf, _ = kalman_update(X.mean(0), np.cov(X.T), H, y, R)
    np.testing.assert_allclose(Xa.mean(0), mean_kf, rtol=0, atol=1e-10)


@pytest.mark.parametrize('method', ['etkf', 'enkf'])
def test_converges_to_the_kalman_filter_as_members_grow(method):
    """
    A 20-step linear Gaussian filter (a damped rotation, position measured).

    The ensemble mean and covariance approach the Kalman filter's at the Monte Carlo rate
    N^-1/2.

    The error at N = 400 members is within 6 sqrt(trace P / N) of the exact Kalman mean
    (a sampling error bound) and shrinks by at least a factor 2 from N = 25 (the rate
    predicts 4; averages over 5 seeds); the covariance's relative error at N = 400 is within
    6 sqrt(2 / N), the sampling error of a covariance estimate.
    """
    theta = 0.3
    F = 0.98 * np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    Q = np.diag([0.01, 0.02])
    H = np.array([[1.0, 0.0]])
    R = np.array([[0.05]])
    truth_rng = np.random.default_rng(10)
    x_true = np.array([1.0, 0.0])
    ys = []
    for _ in range(20):
        x_true = F @ x_true + truth_rng.multivariate_normal(np.zeros(2), Q)
        ys.append(H @ x_true + truth_rng.normal(scale=np.sqrt(R[0, 0]), size=1))
    m0, P0 = np.zeros(2), np.eye(2)
    mean_kf, cov_kf = m0, P0
    for y in ys:
        mean_kf, cov_kf = F @ mean_kf, F @ cov_kf @ F.T + Q
        mean_kf, cov_kf = kalman_update(mean_kf, cov_kf, H, y, R)

    def ensemble_errors(members, seed):
        rng = np.random.default_rng(seed)
        X = rng.multivariate_normal(m0, P0, size=members)
        for y in ys:
            X = X @ F.T + rng.multivariate_normal(np.zeros(2), Q, size=members)
            X = analyse(X @ H.T, y, R, method=method, rng=rng).apply(X)
        return (np.linalg.norm(X.mean(0) - mean_kf),
                np.linalg.norm(np.cov(X.T) - cov_kf) / np.linalg.norm(cov_kf))

    small = np.mean([ensemble_errors(25, s) for s in range(5)], axis=0)
    large = np.mean([ensemble_errors(400, s) for s in range(5)], axis=0)
    assert large[0] < 6 * np.sqrt(np.trace(cov_kf) / 400)
    assert large[1] < 6 * np.sqrt(2 / 400)
    assert large[0] < small[0] / 2


@settings(max_examples=30, deadline=None)
@given(members=st.integers(2, 20), inflation=st.floats(1.0, 2.0), seed=st.integers(0, 2**32 - 1))
def test_the_transform_keeps_a_constant_quantity_and_is_affine(members, inflation, seed):
    """
    Each analysed member is an affine combination of the forecast (rows of T sum to 1).

    A quantity equal in every member is left unchanged.
    """
    rng = np.random.default_rng(seed)
    Y = rng.normal(size=(members, 3))
    analysis = analyse(Y, rng.normal(size=3), np.ones(3), inflation=inflation)
    np.testing.assert_allclose(analysis.transform.sum(axis=1), 1.0, atol=1e-9)
    constant = np.full((members, 2), 7.5)
    np.testing.assert_allclose(analysis.apply(constant), constant, atol=1e-9)
    assert analysis.nis >= 0


@settings(max_examples=30, deadline=None)
@given(members=st.integers(2, 30), inflation=st.floats(1.0, 3.0), seed=st.integers(0, 2**32 - 1))
def test_inflation_keeps_the_mean_and_scales_the_spread(members, inflation, seed):
    X = np.random.default_rng(seed).normal(size=(members, 3))
    Z = inflation_transform(members, inflation) @ X
    np.testing.assert_allclose(Z.mean(0), X.mean(0), atol=1e-12)
    np.testing.assert_allclose(Z.std(0), inflation * X.std(0), rtol=1e-9, atol=1e-12)


def test_nis_is_chi_square_in_expectation_when_the_statistics_are_right():
    """
    The innovations of a consistent filter have E[NIS] = p.

    E[NIS] = p (here p = 3, mean over 400 draws within 4 standard errors, sd of chi2_3 =
    sqrt(6)).
    """
    rng = np.random.default_rng(5)
    values = []
    for _ in range(400):
        m, P, H, R, _ = _problem(rng, n=4, p=3)
        x = rng.multivariate_normal(m, P)
        y = H @ x + rng.multivariate_normal(np.zeros(3), R)
        X = _sample(rng, m, P, 100)
        values.append(analyse(X @ H.T, y, R).nis)
    assert abs(np.mean(values) - 3.0) < 4 * np.sqrt(6 / 400) + 0.1


def test_bad_input_is_refused():
    Y = np.zeros((4, 2))
    with pytest.raises(ValueError, match='inflation'):
        analyse(Y, np.zeros(2), np.ones(2), inflation=0.5)
    with pytest.raises(ValueError, match='parameter_inflation'):
        analyse(Y, np.zeros(2), np.ones(2), parameter_inflation=0.9)
    with pytest.raises(ValueError, match='parameter_relaxation'):
        analyse(Y, np.zeros(2), np.ones(2), parameter_relaxation=1.0)
    with pytest.raises(ValueError, match='Generator'):
        analyse(Y, np.zeros(2), np.ones(2), method='enkf')
    with pytest.raises(ValueError, match='shape'):
        analyse(Y, np.zeros(3), np.ones(3))


@settings(max_examples=20, deadline=None)
@given(members=st.integers(3, 20), relaxation=st.floats(0.0, 0.95),
       inflation=st.floats(1.0, 1.5), seed=st.integers(0, 2**32 - 1))
def test_relaxation_keeps_the_analysis_mean_and_blends_the_anomalies(
        members, relaxation, inflation, seed):
    """
    RTPP keeps the analysis mean and blends the anomalies.

    RTPP: the mean is the plain analysis's; the anomalies are (1 - r) A_a + r A_f with A_f the
    (inflated) forecast anomalies.
    """
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(members, 4))
    H = rng.normal(size=(2, 4))
    y, R = rng.normal(size=2), np.array([0.5, 2.0])
    plain = analyse(X @ H.T, y, R, inflation=inflation).apply(X)
    relaxed = analyse(X @ H.T, y, R, inflation=inflation, relaxation=relaxation).apply(X)
    np.testing.assert_allclose(relaxed.mean(0), plain.mean(0), atol=1e-9)
    forecast = inflation * (X - X.mean(0))
    expected = (1 - relaxation) * (plain - plain.mean(0)) + relaxation * forecast
    np.testing.assert_allclose(relaxed - relaxed.mean(0), expected, atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(members=st.integers(3, 20), inflation=st.floats(1.0, 1.5),
       parameter_inflation=st.floats(1.0, 1.5), relaxation=st.floats(0.0, 0.9),
       parameter_relaxation=st.floats(0.0, 0.9), seed=st.integers(0, 2**32 - 1))
def test_the_parameters_own_inflation_and_relaxation(members, inflation, parameter_inflation,
                                                     relaxation, parameter_relaxation, seed):
    """
    The parameters' transform is the same analysis with their own inflation and relaxation.

    The gain is the state's (from the predictions inflated by ``inflation``): with the same
    relaxation, the parameters' change from the forecast mean is the state transform's scaled
    by parameter_inflation / inflation; with their own relaxation, the mean is that and the
    anomalies are blended with the forecast anomalies inflated by parameter_inflation.
    Asking for the state's own values gives the state's transform; asking for none gives None.
    """
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(members, 4))
    H = rng.normal(size=(2, 4))
    y, R = rng.normal(size=2), np.array([0.5, 2.0])
    args = dict(inflation=inflation, relaxation=relaxation)
    assert analyse(X @ H.T, y, R, **args).parameter_transform is None
    same = analyse(X @ H.T, y, R, parameter_inflation=inflation,
                   parameter_relaxation=relaxation, **args)
    np.testing.assert_allclose(same.parameter_transform, same.transform, atol=1e-12)
    mean = X.mean(0)
    scaled = analyse(X @ H.T, y, R, parameter_inflation=parameter_inflation, **args)
    np.testing.assert_allclose(scaled.parameter_transform @ X - mean,
                               parameter_inflation / inflation * (scaled.transform @ X - mean),
                               atol=1e-9)
    own = analyse(X @ H.T, y, R, parameter_inflation=parameter_inflation,
                  parameter_relaxation=parameter_relaxation, **args).parameter_transform @ X
    plain = analyse(X @ H.T, y, R, parameter_inflation=parameter_inflation,
                    inflation=inflation).parameter_transform @ X
    np.testing.assert_allclose(own.mean(0), plain.mean(0), atol=1e-9)
    expected = ((1 - parameter_relaxation) * (plain - plain.mean(0))
                + parameter_relaxation * parameter_inflation * (X - mean))
    np.testing.assert_allclose(own - own.mean(0), expected, atol=1e-9)


def test_a_parameter_the_data_do_not_see_keeps_its_spread_without_its_own_inflation():
    """
    Without information the state's inflation compounds; a parameter without it does not.

    Noise 1e6 times the predictions' spread (at the end): over 200 analyses at inflation
    1.02 the state's anomalies grow by 1.02^200 (about 52), the parameter's
    (parameter_inflation 1) stay within 1e-4 of what they were: the compounding that drove
    a static parameter to its bounds in the 64-member run of docs/ASSIMILATION.md.
    """
    rng = np.random.default_rng(4)
    state, parameter = rng.normal(size=(16, 2)), rng.normal(size=(16, 1))
    start_state, start_parameter = state.std(0), parameter.std(0)
    for _ in range(200):
        analysis = analyse(state[:, :1] + 1e-3 * rng.normal(size=(16, 1)), np.zeros(1),
                           np.array([1e12]), inflation=1.02, parameter_inflation=1.0)
        state, parameter = analysis.apply(state), analysis.parameter_transform @ parameter
    np.testing.assert_allclose(state.std(0), 1.02 ** 200 * start_state, rtol=1e-3)
    np.testing.assert_allclose(parameter.std(0), start_parameter, rtol=1e-4)


def test_the_student_t_bounds_cover_a_new_draw_95_percent_of_the_time():
    """
    8 Gaussian members and a truth drawn alike.

    The Student-t prediction interval holds the truth 95 % of the time (4000 trials, within 4
    standard errors); the members' own 2.5-97.5 % percentiles hold it less than (N - 1)/(N + 1)
    = 78 % of the time.
    """
    from drill_twin.assimilation.bounds import interval

    rng = np.random.default_rng(11)
    draws = rng.normal(size=(4000, 9))
    inside_t, inside_p = [], []
    for row in draws:
        members, truth = row[:8], row[8]
        _, low, high = interval(members, 'student_t')
        inside_t.append(low <= truth <= high)
        _, low, high = interval(members, 'percentile')
        inside_p.append(low <= truth <= high)
    assert abs(np.mean(inside_t) - 0.95) < 4 * np.sqrt(0.95 * 0.05 / 4000)
    assert np.mean(inside_p) < 7 / 9


@pytest.mark.parametrize('members', [2, 3, 8, 64])
def test_the_bounds_are_scipys_student_t_interval_and_numpys_quantiles(members):
    """
    interval() of (N, k) values, column by column, against scipy.stats and numpy.quantile.

    student_t: mean -+ t.ppf(0.975, N - 1) s sqrt(1 + 1/N), s with ddof 1 (12.706 for N = 2);
    percentile: numpy.quantile's 0.025 and 0.975 (linear interpolation).
    """
    from scipy import stats

    from drill_twin.assimilation.bounds import interval

    values = np.random.default_rng(members).gamma(2.0, 3.0, size=(members, 4)) - 5.0
    mean = values.mean(axis=0)
    half = (stats.t.ppf(0.975, members - 1) * values.std(axis=0, ddof=1)
            * np.sqrt(1.0 + 1.0 / members))
    np.testing.assert_allclose(interval(values, 'student_t'),
                               [mean, mean - half, mean + half], rtol=1e-12)
    np.testing.assert_allclose(interval(values, 'percentile'),
                               [mean, *np.quantile(values, [0.025, 0.975], axis=0)], rtol=1e-12)
    assert stats.t.ppf(0.975, 1) == pytest.approx(12.7062047, rel=1e-8)


@settings(max_examples=25, deadline=None)
@given(members=st.integers(8, 24), inflation=st.floats(1.0, 1.5),
       relaxation=st.floats(0.0, 0.9), seed=st.integers(0, 2**31))
def test_localisation_by_motion_is_exact_when_the_motions_are_uncorrelated(
        members, inflation, relaxation, seed):
    """
    For uncorrelated motions, each analysed with its own measurements = the global analysis.

    The members' axial and torsional anomalies span orthogonal subspaces of the members
    (their sample cross-covariance is exactly zero) and each measurement sees one motion:
    then the ETKF's global transform and the transform of each motion's measurements alone
    give the same analysed members, inflation and relaxation included (the case
    ``localisation: motion`` rests on: it drops only cross-covariances that are sampling noise).
    """
    from drill_twin.assimilation.filter import no_information_transform
    rng = np.random.default_rng(seed)
    centred, _ = np.linalg.qr(np.eye(members) - 1.0 / members)
    basis = centred[:, :members - 1]                   # orthonormal, orthogonal to ones
    axial = 1.0 + basis[:, :3] @ rng.standard_normal((3, 3))
    torsional = -2.0 + basis[:, 3:5] @ rng.standard_normal((2, 2))
    h_axial, h_torsional = rng.standard_normal((2, 3)), rng.standard_normal((1, 2))
    Y = np.hstack([axial @ h_axial.T, torsional @ h_torsional.T])
    y = Y.mean(axis=0) + rng.standard_normal(3)
    R = np.array([0.5, 0.7, 0.3])
    T = analyse(Y, y, R, inflation=inflation, relaxation=relaxation).transform
    T_axial = analyse(Y[:, :2], y[:2], R[:2], inflation=inflation,
                      relaxation=relaxation).transform
    T_torsional = analyse(Y[:, 2:], y[2:], R[2:], inflation=inflation,
                          relaxation=relaxation).transform
    np.testing.assert_allclose(T_axial @ axial, T @ axial, atol=1e-10)
    np.testing.assert_allclose(T_torsional @ torsional, T @ torsional, atol=1e-10)
    # A motion no measurement sees: inflation and relaxation only.
    quiet = no_information_transform(members, inflation, relaxation)
    np.testing.assert_allclose(T_axial @ torsional, quiet @ torsional, atol=1e-10)
    np.testing.assert_allclose(quiet @ torsional - (quiet @ torsional).mean(axis=0),
                               inflation * (torsional - torsional.mean(axis=0)), atol=1e-10)
    np.testing.assert_allclose((quiet @ torsional).mean(axis=0), torsional.mean(axis=0))
