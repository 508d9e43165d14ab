"""
How hard the bit lands: the model's peak WOB against the wave estimate, in modes and step.

    python benchmarks/landing_impact.py [--steps 0.01,0.005,0.0025] [--axial-modes 3,10,30]
                                        [--drop 100e3] [--lift 2e3]

The paper's string (axial and torsional, two lateral modes, no wall contact) drills at 2 rad/s,
is lifted by a hook load 2 kN above its weight for 6 s, hangs at its weight for 1 s, then the
hook load drops to the weight minus ``--drop``: the string falls about 1.8 m and lands. Printed
per (axial modes, step): the gap it fell, the bit's axial speed the step before the peak WOB
(on the rock's spring the impact lasts several steps, so this is below the touch-down speed),
the largest |WOB| of the next 6 s, and the force of a landing at that speed on the bottom
section's wave impedance, Z v with Z = A sqrt(E rho) of the collars, which is about what a
continuous rod gives when the rock is stiffer than the rod (the bit-rock law resists a speed
v with v / a2, 12 Z).

docs/ENVELOPE.md, "Landings", holds the table: on the rock's spring
(``bit_rock.contact_stiffness_n_per_m``, the default) the peak WOB converges with the step
(2.09 MN at 5 ms with the paper's 3 axial modes); on a rigid rock it is the one-step stop of
the modal mass and grows without bound as the step shrinks. Not part of the test suite.
"""
from __future__ import annotations

import argparse
import math
import sys

import numpy as np


def landing(time_step_s: float, axial_modes: int, drop_n: float, lift_n: float):
    """Return (gap m, landing speed m/s, peak |WOB| N, Z v N) of one drop."""
    from drill_twin.config import load_config
    from drill_twin.integrator.simulator import Simulator
    from drill_twin.integrator.envelope import StringEnvelope
    from drill_twin.rig.rig import Rig
    config = load_config(None, [
        f'operation.top_drive_speed_hz={2 / (2 * math.pi)}',
        'initial_conditions.steady_twist=true', 'initial_conditions.lateral_deflection_m=0',
        'reduced_basis.lateral_modes=2', 'physics.contact=false', 'physics.finite_strain=false',
        'physics.kinetic_coupling=false', f'integration.time_step_s={time_step_s}',
        f'reduced_basis.axial_modes={axial_modes}'])
    simulator = Simulator(config)
    rig = Rig(simulator)
    prestress = simulator.system.model.prestress
    weight = prestress.hook_load_n - config.bit_rock.static_weight_on_bit_n

    def run(seconds, hook_load_n):
        rig.set_hook_load(hook_load_n)
        rows = []
        for _ in range(int(round(seconds / time_step_s))):
            rig.step()
            o = simulator.observe(detailed=1)
            rows.append((o.weight_on_bit_n[0], o.bit_axial_velocity_m_per_s[0]))
        return np.array(rows)

    run(2.0, prestress.hook_load_n)
    run(6.0, weight + lift_n)
    run(1.0, weight)
    o = simulator.observe(detailed=1)
    gap = float(o.hole_depth_m[0] - o.bit_depth_m[0])
    rows = run(6.0, weight - drop_n)
    peak = int(np.argmax(np.abs(rows[:, 0])))
    speed = float(rows[max(peak - 1, 0), 1])
    impedance = StringEnvelope.of(simulator.system).axial_impedance_n_s_per_m
    return gap, speed, float(abs(rows[peak, 0])), impedance * abs(speed)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--steps', default='0.01,0.005,0.0025')
    parser.add_argument('--axial-modes', default='3,10,30')
    parser.add_argument('--drop', type=float, default=100e3, help='N below the weight')
    parser.add_argument('--lift', type=float, default=2e3, help='N above the weight')
    args = parser.parse_args(argv)
    print('axial modes  step (ms)  gap (m)  landing (m/s)  peak |WOB| (MN)  Z v (MN)  ratio')
    for modes in (int(x) for x in args.axial_modes.split(',')):
        for step in (float(x) for x in args.steps.split(',')):
            gap, speed, peak, wave = landing(step, modes, args.drop, args.lift)
            print(f'{modes:11d}  {1e3 * step:9.2f}  {gap:7.3f}  {speed:13.3f}  '
                  f'{peak / 1e6:15.2f}  {wave / 1e6:8.2f}  {peak / wave:5.1f}', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
