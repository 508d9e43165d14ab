"""Figures of a Monte Carlo study, mirroring the paper's Figs. 7-16."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from drill_twin.viz.figures import MAX_FREQUENCY_HZ, save_figure  # noqa: E402

PANELS = {
    'rop_m_per_s': ('ROP', 'speed [m/s]', 'fig08_rop.png'),
    'weight_on_bit_n': ('weight on bit', 'force [N]', 'fig09a_weight_on_bit.png'),
    'torque_on_bit_nm': ('torque on bit', 'torque [N m]', 'fig09b_torque_on_bit.png'),
    'bit_speed_rad_per_s': ('bit rotation speed', 'speed [rad/s]', 'fig10_bit_speed.png'),
    'radial_displacement_m': ('radial displacement', 'displacement [m]',
                              'fig11_radial_displacement.png'),
}


def plot_study(result, directory: Path) -> list[Path]:
    """Write the study's figures into ``directory``; return their paths."""
    directory = Path(directory)
    delta = result.spec.dispersion
    paths = [_convergence(result, directory / 'fig07_convergence.png')]
    frequency, spectra = result.spectra()
    envelopes = result.envelopes()
    clearance = (result.config.borehole.diameter_m
                 - _outer_diameter_at(result.config, result.spec.station_m)) / 2
    for q, (title, unit, name) in PANELS.items():
        figure, (left, right) = plt.subplots(1, 2, figsize=(11, 3.4),
                                             gridspec_kw={'width_ratios': [1.6, 1]})
        envelope = envelopes[q]
        left.fill_between(result.time_s, envelope.lower, envelope.upper, color='0.8',
                          label='95% confidence limits')
        left.plot(result.time_s, result.mean_model[q], color='k', lw=0.9, label='mean model')
        left.plot(result.time_s, envelope.mean, color='tab:blue', lw=0.9, ls='--',
                  label='mean of the stoch. model')
        if q == 'radial_displacement_m':
            left.axhline(clearance, color='tab:red', ls=':', lw=1, label='borehole')
            title = f'{title}, x = {result.spec.station_m:g} m'
        left.set_title(f'stochastic response, {title} (delta = {delta:g})', fontsize=10)
        left.set_xlabel('time [s]')
        left.set_ylabel(unit)
        left.legend(fontsize=7, loc='upper right')
        model, spectral = spectra[q]
        keep = (frequency > 0) & (frequency <= MAX_FREQUENCY_HZ)
        right.fill_between(frequency[keep], spectral.lower[keep], spectral.upper[keep],
                           color='0.8', label='95% envelope')
        right.semilogy(frequency[keep], model[keep], color='k', lw=0.8, label='mean model')
        right.semilogy(frequency[keep], spectral.mean[keep], color='tab:blue', lw=0.8, ls='--',
                       label='mean of the stoch model')
        right.set_title('frequency spectrum', fontsize=10)
        right.set_xlabel('frequency [Hz]')
        right.set_ylabel(unit.replace('[', 'amplitude ['))
        right.legend(fontsize=7)
        paths.append(save_figure(figure, directory / name))
    paths.append(_realizations(result, directory / 'fig16_rop_realizations.png'))
    return paths


def _outer_diameter_at(config, x_m: float) -> float:
    top = 0.0
    for section in config.sections:
        if x_m <= top + section.length_m:
            return section.outer_diameter_m
        top += section.length_m
    return config.sections[-1].outer_diameter_m


def _convergence(result, path: Path) -> Path:
    conv = result.convergence()
    figure, axis = plt.subplots(figsize=(6, 3.4))
    axis.plot(np.arange(1, conv.size + 1), conv, color='k', lw=1)
    axis.set_xlabel('number of simulations')
    axis.set_ylabel('conv')
    axis.set_title('mean-square convergence (Eq. 54)', fontsize=10)
    return save_figure(figure, path)


def _realizations(result, path: Path, count: int = 12) -> Path:
    figure, axis = plt.subplots(figsize=(8, 3.4))
    rop = result.realizations['rop_m_per_s']
    for k in range(min(count, rop.shape[0])):
        axis.plot(result.time_s, rop[k], lw=0.7)
    lifted = np.flatnonzero(result.lift_offs_in_window[:count] > 0)
    title = f'Monte Carlo realizations of the ROP (delta = {result.spec.dispersion:g})'
    if lifted.size:
        title += f'; the bit lifts off in realizations {lifted.tolist()}'
    axis.set_title(title, fontsize=10)
    axis.set_xlabel('time [s]')
    axis.set_ylabel('speed [m/s]')
    return save_figure(figure, path)
