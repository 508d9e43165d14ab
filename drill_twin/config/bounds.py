"""
Plausibility bounds of the configuration's values, each with the reason it holds.

Every bound lies beyond any real drill string, so that a value outside it is a mistake (a unit
slip, an exponent too many), and the model built from values inside it stays within
floating-point range. The reason goes into the error message.
"""
from __future__ import annotations

# -- the string, the hole, the bit, the set point, damping and integration ------------------
LENGTH_MAX_M = 20_000.0
LENGTH_REASON = 'no well is longer: Kola SG-3 12 262 m, extended-reach wells 15 km'
HOLE_DIAMETER_MAX_M = 2.0
HOLE_DIAMETER_REASON = 'no rotary-drilled hole is wider: conductor holes are about 1.1 m'
ELEMENTS_MAX = 1000
ELEMENTS_REASON = ('the modal analysis is dense: a 6 (N + 1) square mode-shape matrix, '
                   '290 MB at 1000 elements; the paper uses 56')
YOUNG_MODULUS_RANGE_PA = (1.0e9, 1.2e12)
YOUNG_MODULUS_REASON = 'from polymers, 1 GPa, to diamond, 1.2 TPa; steel is 210 GPa'
SOLID_DENSITY_RANGE_KG_PER_M3 = (500.0, 25_000.0)
SOLID_DENSITY_REASON = 'from wood, 500, to osmium, 22 600; steel is 7 850'
SPRING_STIFFNESS_MAX_N_PER_M = 1.0e11
SPRING_STIFFNESS_REASON = ('a solid steel plug filling a 0.6 m hole, one diameter long: '
                           'E pi D / 4 = 1e11 N/m')
FRICTION_COEFFICIENT_MAX = 2.0
FRICTION_REASON = 'steel rubs on rock with 0.1 to 0.6'
MUD_DENSITY_MAX_KG_PER_M3 = 3000.0
MUD_DENSITY_REASON = 'the heaviest drilling muds are about 2 500 kg/m3'
MUD_SPEED_MAX_M_PER_S = 30.0
MUD_SPEED_REASON = 'five times the fastest mud flow in drill pipe, about 6 m/s'
DRAG_COEFFICIENT_MAX = 1.0
DRAG_REASON = 'eighty times the paper\'s skin-friction coefficient, 0.0125'
GRAVITY_MAX_M_PER_S2 = 30.0
GRAVITY_REASON = 'no planet of the solar system pulls harder: Jupiter 24.8, Earth 9.81'
WEIGHT_ON_BIT_MAX_N = 1.0e7
WEIGHT_ON_BIT_REASON = 'twenty times the largest weights on bit, about 0.5 MN'
BIT_MASS_MAX_KG = 1.0e6
BIT_MASS_REASON = ('ten times the heaviest bottom-hole assemblies, about 100 t, were they '
                   'lumped at the bit')
BIT_INERTIA_MAX_KG_M2 = 1.0e5
BIT_INERTIA_REASON = 'twice a 100 t steel cylinder filling a 2 m hole, 5e4 kg m2'
TOP_DRIVE_SPEED_MAX_HZ = 10.0
TOP_DRIVE_SPEED_REASON = 'twice the fastest top drives, 300 rpm = 5 Hz'
TOP_DRIVE_ACCELERATION_MAX_RAD_PER_S2 = 1000.0
TOP_DRIVE_ACCELERATION_REASON = 'a top drive takes about a second, not 0.03 s, to full speed'
HOOK_LOAD_MAX_N = 1.0e8
HOOK_LOAD_REASON = 'ten times the rated hook load of the largest rigs, about 1 000 t'
MASS_DAMPING_MAX_PER_S = 100.0
MASS_DAMPING_REASON = 'more would critically damp every mode below 8 Hz'
STIFFNESS_DAMPING_MAX_S = 0.1
STIFFNESS_DAMPING_REASON = 'more would critically damp every mode above 3.2 Hz'
TIME_STEP_MAX_S = 0.1
TIME_STEP_REASON = ('ten steps per period of 1 Hz, the harmonics of the 0.2 Hz stick-slip; '
                    'the paper uses 5 ms')
TOLERANCE_MAX = 0.1
TOLERANCE_REASON = 'more would accept a Newton step with 10 % of its increment unresolved'
ITERATIONS_MAX = 1000
ITERATIONS_REASON = 'Newton\'s method converges in a few iterations or not at all'

# -- the rig's drives ------------------------------------------------------------------------
DRIVE_INERTIA_MAX_KG_M2 = 1.0e5
DRIVE_INERTIA_REASON = ('fifty times a large top drive (rotor and gearbox referred to the '
                        'main shaft, about 2 000 kg m^2)')
DRIVE_GAIN_MAX = 1.0e9
DRIVE_GAIN_REASON = 'a speed loop stiffer than 1 GN m per rad/s is a unit slip'
DRIVE_TORQUE_MAX_NM = 1.0e6
DRIVE_TORQUE_REASON = 'ten times the largest top drives (about 100 kN m)'
BLOCK_SPEED_MAX_M_PER_S = 5.0
BLOCK_SPEED_REASON = 'drawworks hoist at about 2 m/s at most'
LINE_STIFFNESS_MAX_N_PER_M = 1.0e10
LINE_STIFFNESS_REASON = 'a drill line of 12 lines of 1.5 in wire over 50 m is about 1e8 N/m'

# -- excitation ------------------------------------------------------------------------------
IMBALANCE_MASS_MAX_KG = 1.0e5
IMBALANCE_MASS_REASON = 'the whole 200 m collar section of the paper weighs 57 t'
ECCENTRICITY_MAX_M = 0.5
ECCENTRICITY_REASON = 'a mass centre half a metre off the axis is outside any borehole'
LOBES_MAX = 12
LOBES_REASON = 'roller-cone bits cut 3 lobes; more than 12 is no bottom-hole pattern'
LOBE_AMPLITUDE_MAX_M = 0.02
LOBE_AMPLITUDE_REASON = 'lobes of a bottom-hole pattern are millimetres high, not centimetres'
