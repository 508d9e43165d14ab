"""
Figures of a run: time histories over the stationary window and their spectra.

Spectra are one-sided amplitude spectra of the mean-removed signal (a sinusoid of amplitude A
shows a peak A), drawn on a log scale up to 2 Hz as in the paper.
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from drill_twin.simulation.history import SimulationResult  # noqa: E402
from drill_twin.uncertainty.statistics import fourier_modulus  # noqa: E402

MAX_FREQUENCY_HZ = 2.0
QUANTITIES = (
    ('rop_m_per_s', 'ROP', 'speed [m/s]'),
    ('bit_speed_rad_per_s', 'bit rotation speed', 'speed [rad/s]'),
    ('weight_on_bit_n', 'weight on bit', 'force [N]'),
    ('torque_on_bit_nm', 'torque on bit', 'torque [N m]'),
)


def spectrum(signal: np.ndarray, time_step_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(frequency_hz, amplitude) of the mean-removed signal(s), last axis time."""
    centred = signal - np.mean(signal, axis=-1, keepdims=True)
    return fourier_modulus(centred, time_step_s, scaling='amplitude')


def plot_run(result: SimulationResult, path: str | Path, window_s: float,
             clearance_m: float | None = None, member: int = 0) -> Path:
    """
    Plot time histories and spectra of ROP, bit speed, WOB, TOB and the radial displacement.

    The radial displacement at the first station (the paper's Figs. 8-11 for the mean model).
    """
    mask = result.window(window_s)
    t = result.time_s[mask]
    dt = float(np.median(np.diff(result.time_s)))
    rows = [(result.channels[name][member, mask], title, unit)
            for name, title, unit in QUANTITIES]
    if result.stations_m.size:
        x = result.stations_m[0]
        radial = result.radial_displacement_m()[member, 0, mask]
        rows.append((radial, f'radial displacement, x = {x:g} m', 'displacement [m]'))
    figure, axes = plt.subplots(len(rows), 2, figsize=(11, 2.4 * len(rows)),
                                gridspec_kw={'width_ratios': [1.6, 1]})
    for k, (values, title, unit) in enumerate(rows):
        left, right = axes[k]
        left.plot(t, values, lw=0.8, color='k', label='mean model')
        if 'radial' in title and clearance_m is not None:
            left.axhline(clearance_m, color='tab:red', ls='--', lw=1, label='borehole')
            left.legend(loc='upper right', fontsize=8)
        left.set_title(title, fontsize=10)
        left.set_ylabel(unit)
        frequency, amplitude = spectrum(values, dt)
        keep = (frequency > 0) & (frequency <= MAX_FREQUENCY_HZ)
        right.semilogy(frequency[keep], amplitude[keep], lw=0.8, color='k')
        right.set_title('frequency spectrum', fontsize=10)
        right.set_ylabel(unit.replace('[', 'amplitude ['))
    axes[-1, 0].set_xlabel('time [s]')
    axes[-1, 1].set_xlabel('frequency [Hz]')
    return save_figure(figure, path)


def save_figure(figure, path, dpi: int = 110) -> Path:
    """Lay ``figure`` out tightly, write it to ``path`` (PNG) and close it; return the path."""
    figure.tight_layout()
    path = Path(path)
    figure.savefig(path, dpi=dpi)
    plt.close(figure)
    return path
