"""
The lateral energy balance closes.

E(t) - E(0) equals the work of damping, f_se, f_ke, the wall, the imbalance and the rotating
damping's circulatory force on the lateral DOFs (the identity of the trapezoidal rule), so the
per-term work it reports is where the lateral energy comes from.
"""
from __future__ import annotations

from dataclasses import replace

from imbalanced_string import imbalanced_string as _config

from drill_twin.analysis.power_balance import TERMS, LateralEnergyBalance
from drill_twin.integrator.simulator import Simulator
from drill_twin.rig.rig import Rig


def test_lateral_energy_balance_closes_with_every_term_on():
    """
    The power balance closes with every force of the string acting.

    Coarse string spinning at its BHA resonance with bit-rock law, f_se, f_ke, wall
    contact with friction, an imbalance that drives it into the wall and the rotating
    reading of the beta damping (its circulatory force): over 5 s the
    balance closes to 1e-5 of the work exchanged; the imbalance feeds the lateral motion and
    the damping takes energy out.
    """
    config = _config(4.44, contact=True, finite_strain=True, kinetic_coupling=True,
                     bit_rock=True, time_step_s=0.005)
    # The identity is the fixed step's: steps integrated again on sub-steps at the wall
    # (integration.contact_substeps) follow another path.
    config = replace(config, integration=replace(config.integration, contact_substeps=1))
    imbalance = replace(config.excitation.imbalance, mass_kg=4000.0, eccentricity_m=0.1)
    config = replace(config, excitation=replace(config.excitation, imbalance=imbalance),
                     borehole=replace(config.borehole, friction_coefficient=0.3),
                     lateral_readings=replace(config.lateral_readings,
                                              stiffness_damping='rotating_frame'))
    simulator = Simulator(config)
    rig = Rig(simulator)
    balance = LateralEnergyBalance(simulator)
    touched = False
    for _ in range(1000):
        rig.step()
        balance.update()
        touched |= bool(simulator.last.contact.in_contact.any())
    work = {term: float(balance.work_j[term][0]) for term in TERMS}
    exchanged = sum(abs(w) for w in work.values())
    assert touched and all(work[t] != 0.0 for t in TERMS)
    assert abs(balance.closure_j()[0]) < 1e-5 * exchanged
    assert work['imbalance'] > 0 > work['damping']
    assert balance.energy_j()[0] > 0 == balance.energy_at_start_j[0]
