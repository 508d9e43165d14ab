"""Twin on twin: the ensemble filter against a truth it does not know.

    python benchmarks/assimilation.py [--duration 40] [--members 64] [--out DIR]
                                      [--settle 0 5 10 20] [--scale 1.3 ...]
                                      [--truth-set KEY=VALUE ...]

The truth (rig emulator, :func:`drill_twin.assimilation.rig_emulator.run_rig`): the paper's string
with the bit-rock coefficients a1..a5 changed (default x 1.2, 0.9, 1.1, 1.3, 0.7: up to
+-30 %; this truth drills 0.08-0.12 mm/s, near the law's cutting threshold; ``--scale 1.1
1.15 0.85 1.2 0.8``, the second truth of docs/ASSIMILATION.md, drills 0.7-1.3 mm/s), a germ
at delta = 0.1 (seed 3), 2 % noise on the surface torque plus a bias of
+100 N m (about 2 % of it), 2 mm on the block position; the default schedule (0.83 Hz,
1.0 Hz at 30 s, hook load +10 kN at 60 s, as far as the log goes). The filter starts from
the default configuration (config/ritto2009.yaml: the paper's coefficients) with N members
of germs at its prior dispersion, and uses the surface torque and the block position, with
the filter settings of config/assimilation.yaml (change them with --set assimilation.K=V).
Results: docs/ASSIMILATION.md, "Evidence, twin on twin".

The log goes through the MCAP writer and reader of ``drill-twin rig`` / ``assimilate``. The
scores (the summary keys of ``drill-twin assimilate --summary``) are printed for several
settling times; the estimated law (the default coefficients with the analysed germ's mean,
and with ``--set assimilation.filter.parameters=law`` the members' mean factors of a1..a5)
is compared with the truth's law at the operating point (steady ROP and TOB at 0.83 Hz and
WOB 100 kN), both as the law of the mean germ and as the mean over the analysed members'
laws (the ensemble's estimate of a quantity nonlinear in the germ: near the law's cutting
threshold the ROP of the mean germ is not the members' mean ROP), and the members' axial state
over the last third against the truth's (WOB and bit speed standard deviations, the ROP of
their bits' own steps, their laws' steady ROP at the last set-point); the law the filter held
at the end of each set-point's dwell, there; the mean law's steady ROP at the last set-point
analysis by analysis over the last third (how much the estimate moves). ``--rig-set
assimilation.rig.schedule=[]`` keeps the truth at the paper's operating point. Writes
DIR/rig.mcap, DIR/assimilation.json and DIR/estimate.npz (the estimate's arrays). Slow: the
full model, 2N members.
"""
from __future__ import annotations

from drill_twin.cli import blas_threads

blas_threads.limit_to_one()       # before numpy: two runs side by side must not spin

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from drill_twin.assimilation.offline import run_filter, summarise
from drill_twin.assimilation.rig_emulator import run_rig
from drill_twin.assimilation.settings import load_assimilation
from drill_twin.assimilation.steady_law import steady_point
from drill_twin.cli.rig_files import read_rig_log, write_rig_log
from drill_twin.config import load_config
from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.model.reduced_system import build_reduced_system
from drill_twin.modal.reduced_basis import modal_analysis
from drill_twin.uncertainty.germ import germs_for_realizations

COEFFICIENTS = ('a1_m_per_s', 'a2_m_per_n_s', 'a3_m_per_rad', 'a4_n_rad', 'a5_n_m')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=40.0)
    parser.add_argument('--members', type=int, default=64)
    parser.add_argument('--out', default='assimilation-benchmark')
    parser.add_argument('--settle', type=float, nargs='+', default=[0.0, 5.0, 10.0, 20.0])
    parser.add_argument('--scale', type=float, nargs=5, default=[1.2, 0.9, 1.1, 1.3, 0.7])
    parser.add_argument('--truth-delta', type=float, default=0.1)
    parser.add_argument('--torque-bias', type=float, default=100.0)
    parser.add_argument('--truth-set', dest='truth_overrides', action='append', default=[],
                        metavar='KEY=VALUE', help="the truth's configuration, e.g. "
                        "damping.mass_coefficient_per_s=0.02 (the filter does not know it)")
    parser.add_argument('--set', dest='overrides', action='append', default=[],
                        help='assimilation.KEY=VALUE for the filter')
    parser.add_argument('--rig-set', dest='rig_overrides', action='append', default=[],
                        metavar='KEY=VALUE', help="the rig's, e.g. assimilation.rig.schedule=[] "
                        '(the truth stays at the paper\'s operating point)')
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    filter_config = load_config()
    truth_overrides = [f'bit_rock.{name}={getattr(filter_config.bit_rock, name) * s!r}'
                       for name, s in zip(COEFFICIENTS, args.scale)]
    truth_config = load_config(None, truth_overrides + args.truth_overrides)
    truth_germ = germs_for_realizations(args.truth_delta, 3, [0])[0]
    rig_settings = load_assimilation(None, [
        'assimilation.channels.top_torque.noise_std=0.0',
        'assimilation.channels.top_torque.noise_relative=0.02',
        f'assimilation.channels.top_torque.bias={args.torque_bias!r}',
        'assimilation.channels.block_position.noise_std=0.002', *args.rig_overrides])
    filter_settings = load_assimilation(None, [f'assimilation.filter.members={args.members}',
                                               *args.overrides])
    clock = time.perf_counter()
    model, _, basis = modal_analysis(truth_config)
    truth_log = run_rig(truth_config, rig_settings, args.duration, germ=truth_germ,
                        system=build_reduced_system(model, basis))
    rig_wall = time.perf_counter() - clock
    write_rig_log(out / 'rig.mcap', truth_log, rig_settings, {'duration_s': repr(args.duration)})
    log = read_rig_log(out / 'rig.mcap', filter_settings)
    clock = time.perf_counter()
    model, _, basis = modal_analysis(filter_config)
    estimate = run_filter(filter_config, filter_settings, log, progress=_progress(clock),
                          system=build_reduced_system(model, basis))
    filter_wall = time.perf_counter() - clock

    scores = {f'{s:g}': summarise(estimate, log, s) for s in args.settle if s < log.duration_s}
    percentile = {f'{s:g}': summarise(estimate, log, s, 'percentile')['bit_speed_coverage_95']
                  for s in args.settle if s < log.duration_s}
    a = estimate.arrays()
    np.savez_compressed(out / 'estimate.npz', **a)     # for reading the run again
    germ = np.array([[a['germ_mean'][-1][0], a['germ_mean'][-1][1]],
                     [a['germ_mean'][-1][1], a['germ_mean'][-1][2]]])
    omega = 2 * math.pi * filter_config.operation.top_drive_speed_hz
    wob = -filter_config.bit_rock.static_weight_on_bit_n
    truth_point = steady_point(BitRockLaw.from_config(truth_config.bit_rock), omega, wob,
                               truth_germ)
    prior_point = steady_point(BitRockLaw.from_config(filter_config.bit_rock), omega, wob)
    filter_law = BitRockLaw.from_config(filter_config.bit_rock)
    scales = estimate.final_law_scales                   # None unless parameters is 'law'
    if scales is None:
        scales = np.ones((len(estimate.final_germs), 5))
    estimated_point = steady_point(filter_law.scaled(scales.mean(axis=0)), omega, wob, germ)
    members = np.array([member_point(filter_law.scaled(s), omega, wob, g)
                        for s, g in zip(scales, estimate.final_germs)])
    law = {'truth_rop_m_per_s': truth_point[0], 'truth_tob_nm': truth_point[1],
           'prior_rop_m_per_s': prior_point[0], 'prior_tob_nm': prior_point[1],
           'estimated_rop_m_per_s': estimated_point[0], 'estimated_tob_nm': estimated_point[1],
           'estimated_germ': germ.tolist(), 'truth_germ': truth_germ.tolist(),
           'estimated_law_scales': scales.mean(axis=0).tolist(),
           'estimated_law_scales_bounds': np.percentile(scales, [2.5, 97.5], axis=0).tolist(),
           'ensemble_rop_m_per_s': float(members[:, 0].mean()),
           'ensemble_tob_nm': float(members[:, 1].mean()),
           'ensemble_rop_bounds_m_per_s': np.percentile(members[:, 0], [2.5, 97.5]).tolist(),
           'ensemble_tob_bounds_nm': np.percentile(members[:, 1], [2.5, 97.5]).tolist(),
           'members_not_drilling': int(np.sum(members[:, 0] == 0.0))}
    law['rop_relative_error'] = law['estimated_rop_m_per_s'] / law['truth_rop_m_per_s'] - 1
    law['tob_relative_error'] = law['estimated_tob_nm'] / law['truth_tob_nm'] - 1
    law['ensemble_rop_relative_error'] = law['ensemble_rop_m_per_s'] / law['truth_rop_m_per_s'] - 1
    law['ensemble_tob_relative_error'] = law['ensemble_tob_nm'] / law['truth_tob_nm'] - 1
    law['prior_rop_relative_error'] = law['prior_rop_m_per_s'] / law['truth_rop_m_per_s'] - 1
    law['prior_tob_relative_error'] = law['prior_tob_nm'] / law['truth_tob_nm'] - 1
    # What the twin drills: the hole's mean rate over the last third of the log, truth and
    # ensembles (the truth oscillates: its law is never at its steady point).
    window = a['time_s'] >= 2.0 * log.duration_s / 3.0
    t_w = a['time_s'][window]
    truth_hole = np.interp(t_w, log.truth.time_s, log.truth.hole_depth_m)
    drilled = {'window_s': [float(t_w[0]), float(t_w[-1])],
               'truth_rop_m_per_s': float(np.polyfit(t_w, truth_hole, 1)[0]),
               'filtered_rop_m_per_s': float(np.polyfit(t_w, a['hole_depth_m'][window, 0], 1)[0]),
               'open_loop_rop_m_per_s': float(np.polyfit(t_w, a['hole_depth_m'][window, 1],
                                                         1)[0])}
    law['drilled'] = drilled
    # The same comparison at every set-point the log visited (the law the twin saw last is
    # that of the last one): the mean law of the analysed members against the truth's.
    estimated_law = filter_law.scaled(scales.mean(axis=0))
    truth_law = BitRockLaw.from_config(truth_config.bit_rock)
    visited, hz, weight = [], filter_config.operation.top_drive_speed_hz, wob
    points = [(0.0, hz, weight)]
    for point in rig_settings.rig.schedule:
        if point.time_s >= log.duration_s:
            break
        hz = point.top_drive_speed_hz if point.top_drive_speed_hz is not None else hz
        weight = (wob - point.hook_load_change_n if point.hook_load_change_n is not None
                  else weight)
        points.append((point.time_s, hz, weight))
    for since, hz, weight in points:
        speed = 2 * math.pi * hz
        t_rop, t_tob = steady_point(truth_law, speed, weight, truth_germ)
        e_rop, e_tob = steady_point(estimated_law, speed, weight, germ)
        visited.append({'from_s': since, 'top_drive_speed_hz': hz, 'weight_on_bit_n': weight,
                        'truth_rop_m_per_s': t_rop, 'truth_tob_nm': t_tob,
                        'estimated_rop_m_per_s': e_rop, 'estimated_tob_nm': e_tob,
                        'rop_relative_error': e_rop / t_rop - 1,
                        'tob_relative_error': e_tob / t_tob - 1})
    # How much the mean law's steady ROP at the last set-point moves from analysis to analysis
    # over the last third of the log (the estimate a driller reads there, second by second).
    _, hz, weight = points[-1]
    moving = [steady_point(filter_law.scaled(a['law_mean'][k])
                           if np.all(np.isfinite(a['law_mean'][k])) else filter_law,
                           2 * math.pi * hz, weight,
                           np.array([[a['germ_mean'][k][0], a['germ_mean'][k][1]],
                                     [a['germ_mean'][k][1], a['germ_mean'][k][2]]]))[0]
              for k in np.flatnonzero(a['analysis_time_s'] >= 2.0 * log.duration_s / 3.0)]
    moving = np.array(moving) / visited[-1]['truth_rop_m_per_s'] - 1
    law['last_set_point_rop_relative_error_over_last_third'] = {
        'mean': float(np.nanmean(moving)), 'std': float(np.nanstd(moving)),
        'p5': float(np.nanpercentile(moving, 5)), 'p95': float(np.nanpercentile(moving, 95)),
        'within_10_percent': float(np.mean(np.abs(moving) <= 0.1))}
    law['at_visited_set_points'] = visited
    # How long the law takes: the mean law at chosen times, at the set-point the rig is at
    # then, against the truth's there.
    by_time = []
    for when in (10, 20, 30, 45, 60, 90, 120, 150, 200, 250, 300, 450, 600):
        k = int(np.searchsorted(a['analysis_time_s'], when - 1e-9))
        if when > log.duration_s or k >= a['analysis_time_s'].size:
            break
        v = [p for p, (since, _, _) in zip(visited, points)
             if since <= a['analysis_time_s'][k]][-1]
        g = a['germ_mean'][k]
        rop, tob = steady_point(filter_law.scaled(a['law_mean'][k])
                                if np.all(np.isfinite(a['law_mean'][k])) else filter_law,
                                2 * math.pi * v['top_drive_speed_hz'], v['weight_on_bit_n'],
                                np.array([[g[0], g[1]], [g[1], g[2]]]))
        by_time.append({'time_s': float(a['analysis_time_s'][k]),
                        'rop_relative_error': rop / v['truth_rop_m_per_s'] - 1,
                        'tob_relative_error': tob / v['truth_tob_nm'] - 1})
    law['at_current_set_point_by_time'] = by_time
    # The law the twin held while the rig was at each set-point (its last analysis before the
    # next change), at that set-point: what a driller reads there. The final law above is
    # that of the last set-point; at the earlier ones it is an extrapolation (the parameters'
    # walk forgets what the earlier points told).
    ends = [p[0] for p in points[1:]] + [log.duration_s]
    for v, end in zip(visited, ends):
        k = int(np.searchsorted(a['analysis_time_s'], end - 1e-9)) - 1
        if k < 0:
            continue
        g = a['germ_mean'][k]
        held_germ = np.array([[g[0], g[1]], [g[1], g[2]]])
        held_law = (filter_law.scaled(a['law_mean'][k]) if np.all(np.isfinite(a['law_mean'][k]))
                    else filter_law)
        h_rop, h_tob = steady_point(held_law, 2 * math.pi * v['top_drive_speed_hz'],
                                    v['weight_on_bit_n'], held_germ)
        v.update({'held_at_s': float(a['analysis_time_s'][k]), 'held_rop_m_per_s': h_rop,
                  'held_tob_nm': h_tob,
                  'held_rop_relative_error': h_rop / v['truth_rop_m_per_s'] - 1,
                  'held_tob_relative_error': h_tob / v['truth_tob_nm'] - 1})
    # The analysed members' axial state over the last third, against the truth's: how much
    # they oscillate, what their bits drill by their own steps, and where their laws' steady
    # point is at the last set-point (an oscillating bit drills faster than its steady point).
    late = a['time_s'] >= 2.0 * log.duration_s / 3.0
    truth_late = log.truth.time_s >= 2.0 * log.duration_s / 3.0
    steady = np.array([member_point(filter_law.scaled(s), 2 * math.pi * hz, weight, g)[0]
                       for s, g in zip(scales, estimate.final_germs)])
    axial = {'window_s': drilled['window_s'],
             'members_weight_on_bit_std_n':
                 float(a['filtered_weight_on_bit_n'][late].std(axis=0).mean()),
             'truth_weight_on_bit_std_n': float(log.truth.weight_on_bit_n[truth_late].std()),
             'members_bit_speed_std_rad_per_s': float(a['filtered'][late].std(axis=0).mean()),
             'truth_bit_speed_std_rad_per_s':
                 float(log.truth.bit_speed_rad_per_s[truth_late].std()),
             'members_rop_m_per_s': float(a['filtered_rop_m_per_s'][late].mean()),
             'truth_rop_m_per_s': float(log.truth.rop_m_per_s[truth_late].mean()),
             'members_steady_rop_at_last_set_point_m_per_s': steady.tolist(),
             'truth_steady_rop_at_last_set_point_m_per_s': visited[-1]['truth_rop_m_per_s']}
    closed = np.isfinite(a['hole_rate_observed'])
    windows = [{'analysis_time_s': t, 'observed_m_per_s': o, 'members_mean_m_per_s': p}
               for t, o, p in zip(a['analysis_time_s'][closed], a['hole_rate_observed'][closed],
                                  a['hole_rate_predicted'][closed])]
    result = {'duration_s': log.duration_s, 'members': args.members,
              'rig_overrides': args.rig_overrides,
              'truth_scale': args.scale, 'truth_delta': args.truth_delta,
              'torque_bias_nm': args.torque_bias, 'truth_overrides': args.truth_overrides,
              'filter': repr(filter_settings.filter),
              'rig_wall_s': rig_wall, 'filter_wall_s': filter_wall,
              'scores_by_settle_s': scores, 'percentile_coverage_by_settle_s': percentile,
              'law_at_operating_point': law, 'axial_state': axial,
              'nis_per_measurement': (a['nis'] / a['measurements']).tolist(),
              'hole_rate_windows': windows,
              'analysis_time_s': a['analysis_time_s'].tolist()}
    (out / 'assimilation.json').write_text(json.dumps(result, indent=2) + '\n')
    print(f'{log.duration_s:g} s, {args.members} members; rig {rig_wall:.0f} s, filter '
          f'{filter_wall:.0f} s of wall time')
    print('settle s | RMS error rad/s | open loop | ratio | coverage 95 | open-loop coverage')
    for settle, s in scores.items():
        ratio = s['bit_speed_rms_error_rad_per_s'] / s['open_loop_bit_speed_rms_error_rad_per_s']
        print(f'{settle:>8} | {s["bit_speed_rms_error_rad_per_s"]:15.3f} | '
              f'{s["open_loop_bit_speed_rms_error_rad_per_s"]:9.3f} | {ratio:5.2f} | '
              f'{s["bit_speed_coverage_95"]:11.2f} | {s["open_loop_bit_speed_coverage_95"]:.2f}')
    print(f'steady ROP at the operating point: truth {law["truth_rop_m_per_s"] * 1e3:.3f} mm/s, '
          f'estimated {law["estimated_rop_m_per_s"] * 1e3:.3f} '
          f'({100 * law["rop_relative_error"]:+.1f} %), prior '
          f'{law["prior_rop_m_per_s"] * 1e3:.3f} ({100 * law["prior_rop_relative_error"]:+.1f} %)')
    print(f'steady TOB: truth {law["truth_tob_nm"]:.0f} N m, estimated '
          f'{law["estimated_tob_nm"]:.0f} ({100 * law["tob_relative_error"]:+.1f} %), prior '
          f'{law["prior_tob_nm"]:.0f} ({100 * law["prior_tob_relative_error"]:+.1f} %)')
    for j, channel in enumerate(estimate.bias_channels):
        print(f'estimated {channel} sensor bias: {a["bias_mean"][-1][j]:.4g} '
              f'({a["bias_lower"][-1][j]:.4g} ... {a["bias_upper"][-1][j]:.4g}); the truth\'s '
              f'top_torque bias {args.torque_bias:g} N m')
    low, high = law['ensemble_rop_bounds_m_per_s']
    print(f'the analysed members\' laws (mean over members, 95 % of them): ROP '
          f'{law["ensemble_rop_m_per_s"] * 1e3:.3f} mm/s ({100 * law["ensemble_rop_relative_error"]:+.1f} %; '
          f'{low * 1e3:.3f} ... {high * 1e3:.3f}), TOB {law["ensemble_tob_nm"]:.0f} N m '
          f'({100 * law["ensemble_tob_relative_error"]:+.1f} %); {law["members_not_drilling"]} '
          f'of {len(members)} do not drill there')
    print(f'ROP drilled over {drilled["window_s"][0]:.0f}-{drilled["window_s"][1]:.0f} s (the '
          f'hole\'s rate): truth {drilled["truth_rop_m_per_s"] * 1e3:.3f} mm/s, analysed members '
          f'{drilled["filtered_rop_m_per_s"] * 1e3:.3f} '
          f'({100 * (drilled["filtered_rop_m_per_s"] / drilled["truth_rop_m_per_s"] - 1):+.1f} %), '
          f'open loop {drilled["open_loop_rop_m_per_s"] * 1e3:.3f}')
    print(f'members over {axial["window_s"][0]:.0f}-{axial["window_s"][1]:.0f} s (truth): WOB std '
          f'{axial["members_weight_on_bit_std_n"]:.0f} N ({axial["truth_weight_on_bit_std_n"]:.0f}), '
          f'bit speed std {axial["members_bit_speed_std_rad_per_s"]:.3f} rad/s '
          f'({axial["truth_bit_speed_std_rad_per_s"]:.3f}), ROP by their own steps '
          f'{axial["members_rop_m_per_s"] * 1e3:.4f} mm/s ({axial["truth_rop_m_per_s"] * 1e3:.4f}); '
          f'their laws\' steady ROP at the last set-point {steady.mean() * 1e3:.4f} mm/s, '
          f'{steady.min() * 1e3:.4f} ... {steady.max() * 1e3:.4f} '
          f'({axial["truth_steady_rop_at_last_set_point_m_per_s"] * 1e3:.4f})')
    print('the mean law at the set-point of the moment: ' + ', '.join(
        f'{b["time_s"]:.0f} s ROP {100 * b["rop_relative_error"]:+.1f} % TOB '
        f'{100 * b["tob_relative_error"]:+.1f} %' for b in law['at_current_set_point_by_time']))
    m = law['last_set_point_rop_relative_error_over_last_third']
    print(f'the mean law\'s steady ROP at the last set-point, analysis by analysis over the last '
          f'third: {100 * m["mean"]:+.1f} % mean, {100 * m["std"]:.1f} % std, '
          f'{100 * m["p5"]:+.1f} ... {100 * m["p95"]:+.1f} % (5-95 %), within 10 % '
          f'{100 * m["within_10_percent"]:.0f} % of the time')
    for w in windows:
        print(f'hole-rate window closed at {w["analysis_time_s"]:.1f} s: block slope '
              f'{w["observed_m_per_s"] * 1e3:.3f} mm/s, members\' own {w["members_mean_m_per_s"] * 1e3:.3f}')
    for v in visited:
        where = (f'law at {v["top_drive_speed_hz"]:g} Hz, WOB {v["weight_on_bit_n"] / 1e3:g} kN '
                 f'(from {v["from_s"]:g} s): ROP truth {v["truth_rop_m_per_s"] * 1e3:.3f} mm/s, ')
        if math.isnan(v['rop_relative_error']):
            print(where + 'the estimated law does not drill there (no steady point)')
            continue
        print(where + f'estimated {100 * v["rop_relative_error"]:+.1f} %; TOB truth '
              f'{v["truth_tob_nm"]:.0f} N m, estimated {100 * v["tob_relative_error"]:+.1f} %')
        if 'held_at_s' in v:
            print(f'  the law held there at {v["held_at_s"]:.0f} s: ROP '
                  f'{100 * v["held_rop_relative_error"]:+.1f} %, TOB '
                  f'{100 * v["held_tob_relative_error"]:+.1f} %')


def _progress(clock):
    """Return a progress callback that prints model time and wall time every 10 s of log."""
    def report(time_s, duration_s):
        if abs(time_s / 10.0 - round(time_s / 10.0)) < 1e-9:
            print(f'  {time_s:5.0f} / {duration_s:g} s of log, {time.perf_counter() - clock:5.0f} s '
                  'of wall', flush=True)
    return report


def member_point(law: BitRockLaw, omega: float, wob: float, germ) -> tuple[float, float]:
    """
    (ROP m/s, TOB N m) of one member's law at the operating point; a law that cannot drill
    there rests on the bottom: ROP 0 and its torque at the smallest ROP.
    """
    rop, tob = steady_point(law, omega, wob, germ)
    if np.isfinite(rop):
        return rop, tob
    low = np.array([1e-9])
    _, torque, _ = law.forces(low, np.array([omega]), np.asarray(germ).reshape(1, 2, 2))
    return 0.0, float(-torque[0])


if __name__ == '__main__':
    main()
