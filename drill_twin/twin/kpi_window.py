"""
The mean model's drilling indicators over a moving window of its steps.

One sample per model step (time s, bit speed rad/s, ROP m/s, WOB N, TOB N m) in a ring
buffer sized to the window; the stick-slip severity, the mechanical specific energy and the
ROP over the window (:mod:`~drill_twin.analysis.kpi`), None where a value cannot be computed.
"""
from __future__ import annotations

import math

import numpy as np

from drill_twin.analysis import kpi


class KpiWindow:
    """
    The samples of the last ``window_s`` seconds of steps of ``dt`` (s) and their KPIs.

    :param borehole_diameter_m: the hole's diameter (the MSE's area).
    """

    def __init__(self, window_s: float, dt: float, borehole_diameter_m: float):
        self.dt = dt
        self.borehole_diameter_m = borehole_diameter_m
        self._buffer = RingBuffer(5, 2)
        self.window_s = window_s

    @property
    def window_s(self) -> float:
        return self._window_s

    @window_s.setter
    def window_s(self, seconds: float) -> None:
        """Set the window (s); the ring buffer holds one sample per model step."""
        self._window_s = float(seconds)
        self._buffer.resize(int(math.ceil(self._window_s / self.dt)) + 1)

    def append(self, time_s: float, speed_rad_per_s: float, rop_m_per_s: float,
               weight_on_bit_n: float, torque_on_bit_nm: float) -> None:
        """Add one step's sample."""
        self._buffer.append((time_s, speed_rad_per_s, rop_m_per_s, weight_on_bit_n,
                             torque_on_bit_nm))

    def start_s(self, now_s: float) -> float:
        """Return the time of the window's start (s) at ``now_s``: the samples at or after it."""
        return now_s - self._window_s - 1e-9

    def samples(self, now_s: float) -> np.ndarray:
        """
        Return the samples inside the window at ``now_s``, one per step, in time order.

        Columns time (s), bit speed (rad/s), ROP (m/s), WOB (N), TOB (N m); shape (n, 5).
        """
        window = self._buffer.values()
        return window[window[:, 0] >= self.start_s(now_s)]

    def kpis(self, now_s: float) -> tuple[float | None, float | None, float | None]:
        """
        (stick-slip severity, MSE in Pa, ROP in m/h) over the window at ``now_s``.

        None where a value cannot be computed (fewer than two samples, non-finite).
        """
        times, speed, rop, wob, tob = self._buffer.stored()   # (in any order)
        count, speed, fastest, slowest, rop, wob, power = kpi.window_means(
            times, self.start_s(now_s), speed, rop, wob, tob)
        if count < 2:
            return None, None, None
        ssi = kpi.severity_of(speed, fastest, slowest)
        mse = kpi.specific_energy_of(wob, power, rop, self.borehole_diameter_m)
        rop = 3600.0 * rop
        return tuple(float(v) if np.isfinite(v) else None for v in (ssi, mse, rop))


def quantiles(values: np.ndarray, *probabilities):
    """
    Quantiles along axis 0 by linear interpolation (numpy's default method), computed directly.

    np.quantile's overhead dominates for a handful of members.
    """
    ordered = np.sort(values, axis=0)
    last = ordered.shape[0] - 1
    out = []
    for p in probabilities:
        position = p * last
        low = int(np.floor(position))
        high = min(low + 1, last)
        weight = position - low
        out.append(ordered[low] + weight * (ordered[high] - ordered[low]))
    return out


class RingBuffer:
    """
    The last ``capacity`` rows of ``width`` floats.

    Stored by column, each contiguous: the KPIs reduce the columns of the whole window at
    every tick (:meth:`stored`, in storage order: means and extremes do not need time order),
    which on rows in time order cost a copy of the window and strided reductions (2001 rows
    of 5: 110-160 us a tick against 70-100, the rest numpy's cost per call, measured).
    """

    def __init__(self, width: int, capacity: int):
        self._data = np.zeros((width, capacity))
        self._count = 0

    def resize(self, capacity: int) -> None:
        kept = self.values()[-capacity:]
        self._data = np.zeros((self._data.shape[0], capacity))
        self._data[:, :kept.shape[0]] = kept.T
        self._count = kept.shape[0]

    def append(self, row) -> None:
        capacity = self._data.shape[1]
        self._data[:, self._count % capacity] = row
        self._count += 1

    def values(self) -> np.ndarray:
        """Return the rows in time order, (n, width) (a copy)."""
        capacity = self._data.shape[1]
        if self._count <= capacity:
            return self._data[:, :self._count].T.copy()
        start = self._count % capacity
        return np.concatenate([self._data[:, start:], self._data[:, :start]], axis=1).T

    def stored(self) -> np.ndarray:
        """Return the columns as stored, (width, n): each row once, not in time order (a view)."""
        return self._data[:, :min(self._count, self._data.shape[1])]
