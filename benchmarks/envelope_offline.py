"""The driller's envelope offline: a brutal command sequence through a batch, no ROS.

    python benchmarks/envelope_offline.py [--time-step 0.01] [--delta 0.01] [--members 16]
                                          [--seed 7] [--scale 1.0]

A batch (member 0 the mean model, the others germs of dispersion delta) of the full paper
model goes through: drilling at 5.2 rad/s; 15 rad/s; the hook load lowered by 50 kN, then by
150 kN (WOB about 250 kN: the bit turns backwards); the top drive stopped with the bit on
bottom and restarted; 30 rad/s with WOB 300 kN; the bit picked up off bottom (hook load above
the string's weight), set down again; back to the paper's point. A step that fails even on
dt/16 is handled as the twin does (the member restarted from a safe state, the step
retried). Prints per phase the retried member-steps, sub-steps, restarts, the lowest bit speed
and how many members were off bottom, and the wall time. ``--scale`` shortens every phase.

The hook load is a force: 20 s at the weight + 40 kN, then 20 s at the weight - 30 kN, fling
the string some 140 m up; back at the drilling hook load it falls and tags bottom at about
14 m/s (a brutal landing, far outside what a driller does, kept as a stress test). Its
result: docs/ENVELOPE.md, "Evidence".
"""
from __future__ import annotations

import argparse
import time

import numpy as np
from threadpoolctl import threadpool_limits

from drill_twin.config import load_config
from drill_twin.model.reduced_system import build_reduced_system
from drill_twin.integrator.simulator import SimulationDiverged, Simulator
from drill_twin.modal.reduced_basis import modal_analysis
from drill_twin.rig.rig import Rig
from drill_twin.uncertainty.germ import germs_for_realizations


def phases(rig: Rig):
    """(name, seconds, top speed or None, hook load or None)."""
    static = rig.hook_load_command_n
    weight = static - rig.config.bit_rock.static_weight_on_bit_n
    return [('paper point', 20, 5.2, static), ('15 rad/s', 40, 15.0, None),
            ('hook -50 kN', 50, None, static - 5e4), ('hook -150 kN', 90, None, static - 1.5e5),
            ('stopped on bottom', 30, 0.0, None), ('restarted 15 rad/s', 30, 15.0, None),
            ('30 rad/s, WOB 300 kN', 50, 30.0, weight - 3e5),
            ('picked up', 20, 5.2, weight + 4e4), ('set down', 20, None, weight - 3e4),
            ('paper point again', 30, 5.2, static)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--time-step', type=float, default=0.01)
    parser.add_argument('--delta', type=float, default=0.01)
    parser.add_argument('--members', type=int, default=16)
    parser.add_argument('--seed', type=int, default=7)
    parser.add_argument('--scale', type=float, default=1.0)
    args = parser.parse_args()
    config = load_config(None, [f'integration.time_step_s={args.time_step}'])
    with threadpool_limits(limits=1, user_api='blas'):
        model, _, basis = modal_analysis(config)
        system = build_reduced_system(model, basis)
        germs = germs_for_realizations(args.delta, args.seed, range(args.members))
        germs[0] = np.eye(2)
        simulator = Simulator(config, members=args.members, germs=germs, system=system)
        rig = Rig(simulator)
        restarts = 0
        start = time.perf_counter()
        print(f'dt = {args.time_step} s, delta = {args.delta}, {args.members} members')
        for name, seconds, speed, hook in phases(rig):
            if speed is not None:
                rig.set_top_drive_speed(speed)
            if hook is not None:
                rig.set_hook_load(hook)
            retries, substeps, lowest, off = simulator.retries, simulator.substeps, np.inf, 0
            phase_restarts = 0
            for _ in range(int(round(args.scale * seconds / simulator.dt))):
                try:
                    rig.step()
                except SimulationDiverged as error:        # what the twin would do
                    phase_restarts += len(error.members)
                    rig.reset_members(error.members)
                    continue
                lowest = min(lowest, float(simulator.last.bit_speed_rad_per_s.min()))
                off = max(off, int(np.sum(~simulator.on_bottom())))
            restarts += phase_restarts
            o = simulator.observe(detailed=0)
            print(f'{name:>22}: t = {simulator.time_s:7.2f} s, retried member-steps '
                  f'{simulator.retries - retries}, sub-steps {simulator.substeps - substeps}, '
                  f'restarts {phase_restarts}, lowest bit speed {lowest:.2f} rad/s, '
                  f'members off bottom (max) {off}, mean WOB {o.weight_on_bit_n.mean() / 1e3:.0f} '
                  f'kN', flush=True)
        wall = time.perf_counter() - start
    print(f'total: {simulator.retries} retried member-steps, {simulator.substeps} sub-steps, '
          f'{restarts} restarts, {simulator.time_s:.0f} s simulated in {wall:.0f} s')


if __name__ == '__main__':
    main()
