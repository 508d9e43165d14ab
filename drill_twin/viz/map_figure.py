"""
The stick-slip map figure: stick-slip severity over top-drive speed x weight on bit.

Cells are coloured by the SSI of the simulated points; the contours SSI = 0.5 and 1 separate
no stick-slip / stick-slip / full stick (the bit stops); points where the bit turned
backwards are marked, failed points crossed out (their cells are left blank and the
contours stop short of them); the dashed line is the linear stability
boundary (growth rate 0) of steady drilling computed on a fine grid, the dotted one where the
bit-rock law's steady ROP vanishes.
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from drill_twin.simulation.stick_slip_map import (  # noqa: E402
    RAD_PER_S_TO_RPM, SSI_FULL_STICK, SSI_STICK_SLIP, MapResult)

PAPER_POINT = (2 * np.pi * 0.83, 100e3)
"""The paper's operating point: 0.83 Hz at the top, 100 kN on the bit."""


def _edges(centres: np.ndarray) -> np.ndarray:
    """Cell edges around sorted centres (half a step beyond the ends)."""
    if centres.size == 1:
        half = max(abs(centres[0]) * 0.1, 1.0)
        return np.array([centres[0] - half, centres[0] + half])
    middle = 0.5 * (centres[1:] + centres[:-1])
    return np.concatenate([[2 * centres[0] - middle[0]], middle, [2 * centres[-1] - middle[-1]]])


def plot_map(result: MapResult, path: str | Path) -> Path:
    """Draw the map into ``path`` (PNG)."""
    spec = result.spec
    speeds = np.array(spec.speeds_rad_per_s)
    weights = np.array(spec.weights_on_bit_n)
    order_s, order_w = np.argsort(speeds), np.argsort(weights)
    speeds, weights = speeds[order_s], weights[order_w]
    ssi = result.column('stick_slip_severity')[np.ix_(order_w, order_s)]
    backward = result.column('backward_rotation')[np.ix_(order_w, order_s)] == 1
    failed = result.column('failed')[np.ix_(order_w, order_s)] == 1
    kn = 1e-3

    figure, axes = plt.subplots(figsize=(8.0, 6.4), constrained_layout=True)
    finite = ssi[np.isfinite(ssi)]
    top = max(1.2, float(finite.max())) if finite.size else 1.2
    mesh = axes.pcolormesh(_edges(speeds), _edges(weights) * kn, np.ma.masked_invalid(ssi),
                           cmap='viridis', vmin=0.0, vmax=top, shading='flat')
    figure.colorbar(mesh, ax=axes, label='stick-slip severity (omega_max - omega_min) / '
                                         '(2 omega_mean)')
    handles = []
    if speeds.size > 1 and weights.size > 1 and finite.size:
        lines = axes.contour(speeds, weights * kn, np.ma.masked_invalid(ssi),
                             levels=[SSI_STICK_SLIP, SSI_FULL_STICK], colors=['cyan', 'red'],
                             linewidths=1.6)
        axes.clabel(lines, fmt={SSI_STICK_SLIP: 'stick-slip', SSI_FULL_STICK: 'full stick'},
                    fontsize=8)
        handles += [Line2D([], [], color='cyan', lw=1.6,
                           label=f'SSI = {SSI_STICK_SLIP:g}: stick-slip above'),
                    Line2D([], [], color='red', lw=1.6,
                           label=f'SSI = {SSI_FULL_STICK:g}: full stick above')]
    growth = result.boundary_growth_rate_per_s
    if growth.shape[0] > 1 and growth.shape[1] > 1 and np.nanmin(growth) < 0 < np.nanmax(growth):
        axes.contour(result.boundary_speeds_rad_per_s, result.boundary_weights_on_bit_n * kn,
                     growth, levels=[0.0], colors='black', linestyles='--', linewidths=1.8)
        handles.append(Line2D([], [], color='black', ls='--', lw=1.8,
                              label='linear stability boundary (unstable on the '
                                    'velocity-weakening side)'))
    rop = result.boundary_steady_rop_m_per_s
    if rop.shape[0] > 1 and rop.shape[1] > 1 and np.nanmin(rop) < 0 < np.nanmax(rop):
        axes.contour(result.boundary_speeds_rad_per_s, result.boundary_weights_on_bit_n * kn,
                     rop, levels=[0.0], colors='0.6', linestyles=':', linewidths=1.8)
        handles.append(Line2D([], [], color='0.6', ls=':', lw=1.8,
                              label='steady ROP = 0 (the law does not drill below)'))
    grid_s, grid_w = np.meshgrid(speeds, weights * kn)
    axes.plot(grid_s, grid_w, '.', color='0.85', ms=3)
    if np.any(backward):
        axes.plot(grid_s[backward], grid_w[backward], 'v', color='orange', mec='black', ms=8)
        handles.append(Line2D([], [], ls='', marker='v', color='orange', mec='black',
                              label='backward rotation'))
    if np.any(failed):
        axes.plot(grid_s[failed], grid_w[failed], 'x', color='magenta', ms=10, mew=2)
        handles.append(Line2D([], [], ls='', marker='x', color='magenta', mew=2,
                              label='integration failed'))
    paper_speed, paper_wob = PAPER_POINT
    if speeds[0] <= paper_speed <= speeds[-1] and weights[0] <= paper_wob <= weights[-1]:
        axes.plot(paper_speed, paper_wob * kn, '*', color='white', mec='black', ms=14)
        handles.append(Line2D([], [], ls='', marker='*', color='white', mec='black', ms=12,
                              label='the paper: 0.83 Hz, 100 kN'))
    axes.set_xlabel('top-drive speed [rad/s]')
    axes.set_ylabel('weight on bit [kN]')
    rpm = axes.secondary_xaxis('top', functions=(lambda w: w * RAD_PER_S_TO_RPM,
                                                 lambda n: n / RAD_PER_S_TO_RPM))
    rpm.set_xlabel('top-drive speed [rpm]')
    axes.set_title(f'stick-slip map, mean model: last {spec.window_s:g} s of '
                   f'{spec.duration_s:g} s per point', fontsize=10)
    if handles:
        figure.legend(handles=handles, loc='outside lower center', ncols=2, fontsize=7,
                      frameon=False)
    figure.savefig(path, dpi=120)
    plt.close(figure)
    return Path(path)
