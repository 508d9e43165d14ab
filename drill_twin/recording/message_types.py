"""
ROS message classes from type names such as 'sensor_msgs/msg/JointState'.

rosidl_runtime_py (and its ``get_message``) is not on PyPI, so the generated Python package
``<pkg>.msg`` is imported directly.  Importing a message package does not import rclpy.
"""
from __future__ import annotations

import functools
import importlib
import re

_TYPE_NAME = re.compile(r'^([A-Za-z][A-Za-z0-9_]*)/(?:(msg)/)?([A-Za-z][A-Za-z0-9_]*)$')


def split_type_name(type_name: str) -> tuple[str, str]:
    """
    Split 'pkg/msg/Type' (or 'pkg/Type') into ('pkg', 'Type').

    Raises ValueError for anything else (services and actions are not message types).
    """
    match = _TYPE_NAME.match(type_name)
    if match is None:
        raise ValueError(f'not a ROS message type name: {type_name!r} (want pkg/msg/Type)')
    return match.group(1), match.group(3)


def canonical_type_name(type_name: str) -> str:
    """'pkg/Type' or 'pkg/msg/Type' -> 'pkg/msg/Type' (the form rosbag2 stores)."""
    package, name = split_type_name(type_name)
    return f'{package}/msg/{name}'


@functools.lru_cache(maxsize=None)
def import_message_class(type_name: str) -> type:
    """
    Return the generated Python class of a message type, e.g. 'std_msgs/msg/Float64'.

    Raises ValueError for a malformed name, ImportError if the package is not installed and
    AttributeError if the package has no such message.
    """
    package, name = split_type_name(type_name)
    module = importlib.import_module(package + '.msg')
    try:
        return getattr(module, name)
    except AttributeError:
        raise AttributeError(f'package {package!r} has no message {name!r}') from None


def type_name_of(message_or_class: object) -> str:
    """
    'pkg/msg/Type' of a generated message instance or class.

    Generated classes live in modules named '<pkg>.msg._<snake_case_type>'.
    """
    cls = message_or_class if isinstance(message_or_class, type) else type(message_or_class)
    parts = cls.__module__.split('.')
    if len(parts) != 3 or parts[1] != 'msg':
        raise TypeError(f'{cls.__module__}.{cls.__qualname__} is not a generated ROS message')
    return f'{parts[0]}/msg/{cls.__name__}'
