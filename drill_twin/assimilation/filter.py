"""
The ensemble Kalman analysis as a transform of the members (ETKF or stochastic EnKF).

Layout: an ensemble is a matrix X of shape (N, n), members in rows. The analysis of either
method is linear in the members: X_a = T X with an (N, N) matrix T built from the predicted
measurements Y (N, p) of the members, the measurement y (p,) and its noise covariance R (p, p).
Returning T rather than X_a lets the caller apply the same update to any other quantity carried
by the members (the augmented parameters, a buffer of past predicted measurements for
delayed data: an ensemble smoother step), and keeps the filter blind to what the state is.

Methods (Evensen 2009; Hunt, Kostelich & Szunyogh 2007, Physica D 230):

- ``etkf``: the ensemble transform Kalman filter in its symmetric square-root form. With the
  anomalies A = X - mean, S = R^-1/2 (Y - mean_Y)^T / sqrt(N - 1) (p, N) and
  C = I + S^T S (N, N): the mean weights w = C^-1 S^T R^-1/2 (y - mean_Y) / sqrt(N - 1) and
  W = C^-1/2 (symmetric), X_a = mean + (w + W)^T A. Deterministic; for a linear measurement
  operator the analysis mean and covariance are exactly the Kalman filter's applied to the
  ensemble's mean and covariance.
- ``enkf``: the stochastic EnKF with perturbed observations, X_a,i = X_i + K (y + e_i - Y_i),
  K = P_xy (P_yy + R)^-1, e_i ~ N(0, R) drawn from the caller's Generator (centred over the
  ensemble, so the analysis mean is the Kalman one; the covariance only in expectation).

Inflation: multiplicative, anomalies scaled by ``inflation`` (>= 1) before the analysis (of
X and Y alike: Y is taken to be linear in X over the ensemble's spread). Relaxation to the
prior perturbations (RTPP, Zhang, Snyder & Sun 2004): the analysed anomalies blended with the
forecast ones, A_a <- (1 - relaxation) A_a + relaxation A_f, against the collapse of a small
ensemble; also linear in the members, so it is part of the transform. The augmented
parameters may take their own inflation and relaxation (``parameter_inflation``,
``parameter_relaxation``): the same analysis, a second transform
(:attr:`Analysis.parameter_transform`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

METHODS = ('etkf', 'enkf')


@dataclass(frozen=True)
class Analysis:
    """
    The result of one analysis.

    transform: (N, N), X_a = transform @ X for any quantity X (N, ...) carried by the members.
    innovation: y - mean(Y), (p,). innovation_covariance: P_yy + R, (p, p) (after inflation).
    nis: normalised innovation squared, innovation^T (P_yy + R)^-1 innovation (its expectation
    is p when the filter's statistics are right: a health check).
    """

    transform: np.ndarray
    innovation: np.ndarray
    innovation_covariance: np.ndarray
    nis: float
    parameter_transform: np.ndarray | None = None
    """(N, N): the same analysis with the parameters' own inflation and relaxation (None:
    those of the state were asked for, use ``transform``)."""

    @property
    def measurements(self) -> int:
        return int(self.innovation.size)

    def apply(self, members: np.ndarray) -> np.ndarray:
        """Return the analysed ``members``, shape (N, ...) like the input."""
        members = np.asarray(members, dtype=float)
        flat = members.reshape(members.shape[0], -1)
        return (self.transform @ flat).reshape(members.shape)


def inflation_transform(members: int, inflation: float) -> np.ndarray:
    """(N, N) matrix that keeps the mean and scales the anomalies by ``inflation``."""
    centring = np.full((members, members), 1.0 / members)
    return centring + inflation * (np.eye(members) - centring)


def analyse(predicted: np.ndarray, measured: np.ndarray, noise_covariance: np.ndarray, *,
            method: str = 'etkf', inflation: float = 1.0, relaxation: float = 0.0,
            rng: np.random.Generator | None = None, parameter_inflation: float | None = None,
            parameter_relaxation: float | None = None) -> Analysis:
    """
    Return the analysis transform of an ensemble (module docstring).

    :param predicted: Y, (N, p) the measurements each member predicts.
    :param measured: y, (p,) what was measured.
    :param noise_covariance: R, (p, p) symmetric positive-definite, or (p,) its diagonal.
    :param method: 'etkf' or 'enkf'.
    :param inflation: multiplicative inflation of the anomalies (>= 1; 1 = none).
    :param relaxation: RTPP weight of the forecast anomalies in the analysed ones, in [0, 1).
    :param rng: the Generator of the observation perturbations (required for 'enkf').
    :param parameter_inflation, parameter_relaxation: those of a second transform for the
        augmented parameters (None: the state's). The analysis (its gain, from the members'
        predictions inflated by ``inflation``) is the same; only how the anomalies are
        inflated before it and relaxed after it differs: a static parameter has no
        dynamics to spread it again, so inflating it at every analysis compounds.

    :return: :class:`Analysis`; its transform maps the forecast members (not inflated) to the
        analysed ones.
    """
    Y = np.asarray(predicted, dtype=float)
    y = np.asarray(measured, dtype=float).reshape(-1)
    if Y.ndim != 2 or Y.shape[1] != y.size:
        raise ValueError(f'predicted must have shape (N, {y.size}), got {Y.shape}')
    n_members, p = Y.shape
    if n_members < 2:
        raise ValueError(f'an ensemble needs at least 2 members, got {n_members}')
    if method not in METHODS:
        raise ValueError(f'method must be one of {METHODS}, got {method!r}')
    for name, value in (('inflation', inflation), ('parameter_inflation', parameter_inflation)):
        if value is not None and not (math.isfinite(value) and value >= 1.0):
            raise ValueError(f'{name} must be >= 1, got {value!r}')
    for name, value in (('relaxation', relaxation),
                        ('parameter_relaxation', parameter_relaxation)):
        if value is not None and not 0.0 <= value < 1.0:
            raise ValueError(f'{name} must be in [0, 1), got {value!r}')
    R = np.asarray(noise_covariance, dtype=float)
    R = np.diag(R) if R.ndim == 1 else R
    if R.shape != (p, p):
        raise ValueError(f'noise_covariance must have shape ({p}, {p}), got {R.shape}')
    pre = inflation_transform(n_members, inflation)
    Y = pre @ Y
    mean_y = Y.mean(axis=0)
    B = Y - mean_y                                            # (N, p) anomalies
    innovation = y - mean_y
    scale = math.sqrt(n_members - 1)
    covariance = B.T @ B / (n_members - 1) + R                # P_yy + R
    chol_r = np.linalg.cholesky(R)
    S = np.linalg.solve(chol_r, B.T) / scale                  # (p, N) R^-1/2 B^T / sqrt(N-1)
    d = np.linalg.solve(chol_r, innovation) / scale
    if method == 'etkf':
        # C = I + S^T S through the thin SVD S = U diag(sigma) V^T: O(N p^2), not O(N^3).
        U, sigma, Vt = np.linalg.svd(S, full_matrices=False)
        weights = Vt.T @ (sigma / (1.0 + sigma ** 2) * (U.T @ d))           # C^-1 S^T d
        W = np.eye(n_members) + (Vt.T * (1.0 / np.sqrt(1.0 + sigma ** 2) - 1.0)) @ Vt
        # X_a = 1 mean^T + (w 1^T + W)^T A with A = (I - 11^T / N) X (W is symmetric).
        transform = _centred_right(weights[None, :] + W) + 1.0 / n_members
    else:
        if rng is None:
            raise ValueError("method 'enkf' needs a numpy Generator (rng)")
        noise = rng.standard_normal((n_members, p)) @ chol_r.T
        noise -= noise.mean(axis=0)
        # X_a = X + (y + e - Y) (P_yy + R)^-1 B^T A / (N - 1)
        gains = np.linalg.solve(covariance, (y + noise - Y).T).T      # (N, p)
        transform = np.eye(n_members) + _centred_right(gains @ B.T) / (n_members - 1)
    nis = float(innovation @ np.linalg.solve(covariance, innovation))
    parameter_transform = None
    if parameter_inflation is not None or parameter_relaxation is not None:
        parameter_transform = _inflated_and_relaxed(
            transform, inflation if parameter_inflation is None else parameter_inflation,
            relaxation if parameter_relaxation is None else parameter_relaxation)
    return Analysis(transform=_inflated_and_relaxed(transform, inflation, relaxation),
                    innovation=innovation, innovation_covariance=covariance, nis=nis,
                    parameter_transform=parameter_transform)


def no_information_transform(members: int, inflation: float = 1.0,
                             relaxation: float = 0.0) -> np.ndarray:
    """
    (N, N) transform of an analysis that measured nothing: the inflation and RTPP alone.

    What :func:`analyse` gives a quantity no measurement informs: its mean kept, its
    anomalies scaled by the inflation (the RTPP blends the inflated forecast with itself).
    """
    return _inflated_and_relaxed(np.eye(members), inflation, relaxation)


def _inflated_and_relaxed(transform: np.ndarray, inflation: float,
                          relaxation: float) -> np.ndarray:
    """
    Return the transform of the forecast members, given that of the inflated ones.

    ``transform`` maps the members inflated by ``inflation`` to the analysed ones; the result
    maps the forecast (not inflated) members, with RTPP ``relaxation`` applied.
    """
    n_members = transform.shape[0]
    # T @ pre without an O(N^3) product: pre = J + inflation (I - J), J = 11^T / N.
    transform = (1.0 - inflation) * transform.mean(axis=1, keepdims=True) + inflation * transform
    if relaxation > 0:
        pre = inflation_transform(n_members, inflation)
        # RTPP: J T + (1 - r) (I - J) T + r (I - J) pre: the mean kept, anomalies blended.
        mean_rows = transform.mean(axis=0, keepdims=True)                 # J T
        transform = (mean_rows + (1.0 - relaxation) * (transform - mean_rows)
                     + relaxation * (pre - pre.mean(axis=0, keepdims=True)))
    return transform


def _centred_right(matrix: np.ndarray) -> np.ndarray:
    """Return matrix @ (I - 11^T / N) in O(N^2)."""
    return matrix - matrix.mean(axis=1, keepdims=True)


def kalman_update(mean: np.ndarray, covariance: np.ndarray, operator: np.ndarray,
                  measured: np.ndarray, noise_covariance: np.ndarray):
    """
    Return the Kalman filter's analysis (mean, covariance) for a linear operator H (p, n).

    The reference the ensemble methods converge to (Joseph form for the covariance).
    """
    H = np.asarray(operator, dtype=float)
    R = np.asarray(noise_covariance, dtype=float)
    R = np.diag(R) if R.ndim == 1 else R
    S = H @ covariance @ H.T + R
    K = np.linalg.solve(S, H @ covariance).T
    mean_a = mean + K @ (measured - H @ mean)
    I_KH = np.eye(mean.size) - K @ H
    cov_a = I_KH @ covariance @ I_KH.T + K @ R @ K.T
    return mean_a, cov_a
