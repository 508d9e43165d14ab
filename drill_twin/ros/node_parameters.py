"""
The twin's parameters as ROS parameters of its node: declared, overridden, changed at run time.

:data:`~drill_twin.ros.parameters.PARAMETERS` (names, defaults, ranges, descriptions, which
are safe to change) become rclpy parameters with descriptors; the node's
:class:`~drill_twin.ros.parameters.TwinParameters` are handed in as overrides. A change at run
time is checked here (:func:`changed`): an unsafe parameter or ``use_sim_time``, a value not
among the choices, or crossed hook-load limits are refused with a reason; a change accepted
goes to the engine (:func:`apply`).
"""
from __future__ import annotations

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.parameter import Parameter

from drill_twin.ros.build import command_limits
from drill_twin.ros.parameters import (BY_NAME, PARAMETERS, ParameterSpec, TwinParameters,
                                       unsafe_change_reason)

_PARAMETER_TYPES = {bool: Parameter.Type.BOOL, int: Parameter.Type.INTEGER,
                    float: Parameter.Type.DOUBLE, str: Parameter.Type.STRING,
                    tuple: Parameter.Type.STRING_ARRAY}


def parameter(spec: ParameterSpec, value) -> Parameter:
    """Return the ROS parameter ``spec.name`` holding ``value``, typed as its default."""
    kind = _PARAMETER_TYPES[type(spec.default)]
    return Parameter(spec.name, kind, list(value) if isinstance(value, tuple) else value)


def overrides(params: TwinParameters) -> list[Parameter]:
    """
    Return ``params`` as parameter overrides of the node.

    Without the empty arrays: rclpy cannot override with one (the parameter is left unset).
    """
    return [parameter(spec, getattr(params, spec.name)) for spec in PARAMETERS
            if getattr(params, spec.name) != ()]


def descriptor(spec: ParameterSpec) -> ParameterDescriptor:
    """Return the descriptor of ``spec``: its description, range and choices."""
    descriptor = ParameterDescriptor(description=spec.description)
    integer = isinstance(spec.default, int) and not isinstance(spec.default, bool)
    if spec.low is not None and integer:
        descriptor.integer_range = [IntegerRange(from_value=int(spec.low),
                                                 to_value=int(spec.high), step=1)]
    elif spec.low is not None and isinstance(spec.default, float):
        descriptor.floating_point_range = [FloatingPointRange(from_value=float(spec.low),
                                                              to_value=float(spec.high))]
    if spec.choices:
        descriptor.additional_constraints = 'one of: ' + ', '.join(spec.choices)
    return descriptor


def declare(node) -> None:
    """Declare every parameter of the twin on ``node`` (the overrides give their values)."""
    for spec in PARAMETERS:
        default = (Parameter.Type.STRING_ARRAY if isinstance(spec.default, tuple)
                   else spec.default)
        node.declare_parameter(spec.name, default, descriptor(spec))


def changed(params: TwinParameters, parameters) -> tuple[TwinParameters | None, str]:
    """
    Return (the parameters after a change at run time, '') or (None, why it is refused).

    ``parameters``: the rclpy Parameters to set at once (all or none are).
    """
    for item in parameters:
        spec = BY_NAME.get(item.name)
        if item.name == 'use_sim_time' or (spec is not None and not spec.safe):
            return None, unsafe_change_reason(item.name)
        if spec is not None and spec.choices and item.value not in spec.choices:
            return None, f'{item.name} must be one of {spec.choices_text()}'
    updated = params.with_values(**{p.name: p.value for p in parameters if p.name in BY_NAME})
    if updated.hook_load_min_n > updated.hook_load_max_n:
        return None, 'hook_load_min_n must not exceed hook_load_max_n'
    return updated, ''


def apply(engine, params: TwinParameters, updated: TwinParameters) -> None:
    """Give ``engine`` what changed from ``params`` to ``updated`` (both checked)."""
    if (updated.top_drive_controller
            and updated.top_drive_controller != params.top_drive_controller):
        engine.set_top_drive_controller(updated.top_drive_controller)
    engine.limits = command_limits(updated)
    engine.kpi_window_s = float(updated.kpi_window_s)
