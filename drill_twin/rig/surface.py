"""
What a rig's surface sensors read from the mean model, in SI.

The top's speed and the string's torque at the top (a torque sub), the hook load (the
drawworks' line pull when the block is driven, the hook force otherwise), the block position,
the bit and hole depths, the ROP (the hole's deepening rate) and the surface WOB a rig
computes, off-bottom hook load minus hook load (the off-bottom hook load being the string's
weight as the model counts it, :class:`~drill_twin.integrator.envelope.StringEnvelope`).
The twin publishes them (docs/ROS-INTERFACE.md, "Surface readings and the driller's view").
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SurfaceReadings:
    """
    The surface readings (SI).

    speed (rad/s), torque (N m), hook load (N), block position (m, down > 0 from the start),
    bit and hole depth (m), ROP (m/s), surface WOB (N, compression > 0).
    """

    speed_rad_per_s: float
    torque_nm: float
    hook_load_n: float
    block_position_m: float
    bit_depth_m: float
    hole_depth_m: float
    rop_m_per_s: float
    weight_on_bit_n: float


def surface_readings(rig, observation, string_weight_n: float) -> SurfaceReadings:
    """
    Return the readings of member 0 at ``observation`` (the latest of ``rig``'s simulator).

    ``rig``: the :class:`~drill_twin.rig.rig.Rig` that drives it; ``string_weight_n``: the
    off-bottom hook load (N).
    """
    hook = rig.measured_hook_load_n(observation)
    return SurfaceReadings(
        speed_rad_per_s=float(observation.top_speed_rad_per_s),
        torque_nm=float(observation.top_torque_nm[0]), hook_load_n=hook,
        block_position_m=rig.block_position_m(observation),
        bit_depth_m=float(observation.depth_m[0]),
        hole_depth_m=float(observation.hole_depth_m[0]),
        rop_m_per_s=float(observation.rop_m_per_s[0]),
        weight_on_bit_n=float(string_weight_n) - hook)
