"""
Fast decoding of the few fixed-layout CDR messages the viewer plots, without rclpy.

rclpy's ``deserialize_message`` builds a Python message object per record (hundreds of
microseconds a JointState); the viewer needs only numbers, so these decoders read them
straight from the CDR bytes (XCDR1, little endian, as rclpy and rosbag2 write them) with
``struct``: a few microseconds a message.  Alignment counts from the end of the 4-byte
encapsulation header.  Every decoder returns the header stamp in nanoseconds (None for
types without a header) and the values as floats.
"""
from __future__ import annotations

import struct

_HEADER = 4                                  # encapsulation: 00 01 (CDR_LE), options 00 00
_U32 = struct.Struct('<I')
_STAMP = struct.Struct('<iI')


class CdrError(ValueError):
    """The bytes are not a little-endian CDR message of the expected type."""


def _check(data: bytes) -> None:
    if len(data) < _HEADER or data[0] != 0 or data[1] != 1:
        raise CdrError('not a little-endian CDR message (encapsulation '
                       f'{bytes(data[:2]).hex() or "missing"})')


def _align(position: int, size: int) -> int:
    """Round an absolute byte position up to a multiple of ``size`` past the header."""
    relative = position - _HEADER
    return _HEADER + (relative + size - 1) // size * size


def _string_end(data: bytes, position: int) -> int:
    """Position after a CDR string (uint32 length counting the NUL, then the bytes)."""
    position = _align(position, 4)
    (length,) = _U32.unpack_from(data, position)
    return position + 4 + length


def _header(data: bytes) -> tuple[int, int]:
    """(stamp in ns, position after the std_msgs/Header)."""
    _check(data)
    sec, nanosec = _STAMP.unpack_from(data, _HEADER)
    return sec * 1_000_000_000 + nanosec, _string_end(data, _HEADER + 8)


def _doubles(data: bytes, position: int) -> tuple[tuple[float, ...], int]:
    """Read a float64[] sequence: (values, position after it)."""
    position = _align(position, 4)
    (count,) = _U32.unpack_from(data, position)
    position = _align(position + 4, 8) if count else position + 4
    values = struct.unpack_from(f'<{count}d', data, position)
    return values, position + 8 * count


def joint_state(data: bytes) -> tuple[int, tuple, tuple, tuple]:
    """sensor_msgs/JointState: (stamp ns, position, velocity, effort); names skipped."""
    stamp, position = _header(data)
    position = _align(position, 4)
    (names,) = _U32.unpack_from(data, position)
    position += 4
    for _ in range(names):
        position = _string_end(data, position)
    positions, position = _doubles(data, position)
    velocities, position = _doubles(data, position)
    efforts, _ = _doubles(data, position)
    return stamp, positions, velocities, efforts


def vector3_stamped(data: bytes) -> tuple[int, tuple[float, float, float]]:
    """geometry_msgs/Vector3Stamped: (stamp ns, (x, y, z))."""
    stamp, position = _header(data)
    return stamp, struct.unpack_from('<3d', data, _align(position, 8))


def imu(data: bytes) -> tuple[int, tuple[float, float, float], tuple[float, float, float]]:
    """
    sensor_msgs/Imu: (stamp ns, angular velocity (x, y, z), linear acceleration (x, y, z)).

    After the header: orientation (4 doubles) and its covariance (9), angular velocity (3)
    and its covariance (9), linear acceleration (3) and its covariance (9).
    """
    stamp, position = _header(data)
    position = _align(position, 8)
    angular = struct.unpack_from('<3d', data, position + 8 * 13)
    linear = struct.unpack_from('<3d', data, position + 8 * 25)
    return stamp, angular, linear


def float64(data: bytes) -> float:
    """std_msgs/Float64: the value."""
    _check(data)
    return struct.unpack_from('<d', data, _HEADER)[0]


def float64_multi_array_labels(data: bytes) -> tuple[str, ...]:
    """std_msgs/Float64MultiArray: the labels of its layout's dimensions."""
    labels, _ = _multi_array_layout(data)
    return tuple(label.decode() for label in labels)


def float64_multi_array(data: bytes) -> tuple[float, ...]:
    """std_msgs/Float64MultiArray: the data (the layout is skipped)."""
    _, position = _multi_array_layout(data)
    values, _ = _doubles(data, position)
    return values


def _multi_array_layout(data: bytes) -> tuple[list[bytes], int]:
    """Return the labels of a MultiArray's dimensions (bytes) and the position of its data."""
    _check(data)
    position = _HEADER
    (dims,) = _U32.unpack_from(data, position)
    position += 4
    labels = []
    for _ in range(dims):
        end = _string_end(data, position)                       # label
        labels.append(data[_align(position, 4) + 4:end - 1])
        position = _align(end, 4) + 8                           # size, stride
    return labels, _align(position, 4) + 4                      # data_offset
