"""Schemas and type hashes as rosbag2_storage_mcap (Jazzy) writes them, message type lookup."""
from pathlib import Path
import sys

import pytest

from drill_twin.recording import schemas
from drill_twin.recording.message_types import (
    canonical_type_name, import_message_class, split_type_name, type_name_of)

RULE = '=' * 80


def share_msg(package: str, name: str) -> str:
    """Read ``<sys.prefix>/share/<package>/msg/<name>.msg`` verbatim."""
    return (Path(sys.prefix) / 'share' / package / 'msg' / f'{name}.msg').read_bytes().decode()


def msg_headers(schema_text: str) -> list[str]:
    return [line[len('MSG: '):] for line in schema_text.split('\n') if line.startswith('MSG: ')]


def test_joint_state_schema_has_rosbag2_layout():
    # Built by hand: root verbatim, then '\n', 80 '=', 'MSG: <name as written>', the text.
    expected = (share_msg('sensor_msgs', 'JointState')
                + '\n' + RULE + '\nMSG: std_msgs/Header\n' + share_msg('std_msgs', 'Header')
                + '\n' + RULE + '\nMSG: builtin_interfaces/Time\n'
                + share_msg('builtin_interfaces', 'Time'))
    assert schemas.ros2msg_schema('sensor_msgs/msg/JointState') == expected


@pytest.mark.parametrize('type_name, headers', [
    # Order seen in rosbag2's own Jazzy test bag (rosbag2_cpp/test/.../only_topics.mcap):
    # dependencies sorted per file, depth first, each once, same-package names qualified.
    ('rcl_interfaces/msg/ParameterEvent',
     ['builtin_interfaces/Time', 'rcl_interfaces/Parameter', 'rcl_interfaces/ParameterValue']),
    ('rcl_interfaces/msg/Log', ['builtin_interfaces/Time']),
    ('std_msgs/msg/Float64', []),
    ('diagnostic_msgs/msg/DiagnosticArray',
     ['diagnostic_msgs/DiagnosticStatus', 'diagnostic_msgs/KeyValue', 'std_msgs/Header',
      'builtin_interfaces/Time']),
    ('geometry_msgs/msg/WrenchStamped',
     ['geometry_msgs/Wrench', 'geometry_msgs/Vector3', 'std_msgs/Header',
      'builtin_interfaces/Time']),
    ('sensor_msgs/msg/Imu',
     ['geometry_msgs/Quaternion', 'geometry_msgs/Vector3', 'std_msgs/Header',
      'builtin_interfaces/Time']),
    ('std_msgs/msg/Float64MultiArray',
     ['std_msgs/MultiArrayLayout', 'std_msgs/MultiArrayDimension']),
])
def test_dependency_order(type_name, headers):
    assert msg_headers(schemas.ros2msg_schema(type_name)) == headers


def test_field_type_parsing_follows_rosbag2():
    text = '\n'.join([
        '# comment mentioning other_pkg/Ignored type',
        '  # indented comment Ignored2 x',
        'uint8 CONSTANT=3',
        'string NAME="a b"',
        'string<=10 bounded_string',
        'int32[] unbounded',
        'float64[3] fixed',
        'Inner[<=5] bounded_same_package',
        'other_pkg/Thing thing  # trailing comment',
        'Inner plain_same_package',
        'byte b',
        'char c',
        'bool flag true',
        '',
    ])
    assert schemas.msg_dependencies(text, 'my_pkg') == ['my_pkg/Inner', 'other_pkg/Thing']


def test_definitions_found_through_ament_prefix_path(tmp_path, monkeypatch):
    msg_dir = tmp_path / 'share' / 'dt_fake_msgs' / 'msg'
    msg_dir.mkdir(parents=True)
    outer = 'std_msgs/Header header\nInner[] inners\nInner single\n'
    inner = '# Inner\nfloat64 x\nbuiltin_interfaces/Time t\n'
    (msg_dir / 'Outer.msg').write_text(outer)
    (msg_dir / 'Inner.msg').write_text(inner)
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path))
    assert schemas.search_prefixes()[0] == tmp_path
    text = schemas.ros2msg_schema('dt_fake_msgs/msg/Outer')
    # 'dt_fake_msgs/Inner' < 'std_msgs/Header'; Time comes with Inner and is not repeated.
    assert msg_headers(text) == ['dt_fake_msgs/Inner', 'builtin_interfaces/Time',
                                 'std_msgs/Header']
    assert text.startswith(outer + '\n' + RULE + '\nMSG: dt_fake_msgs/Inner\n' + inner)


def test_missing_definition_raises():
    with pytest.raises(schemas.DefinitionNotFoundError):
        schemas.ros2msg_schema('no_such_pkg/msg/Nothing')
    with pytest.raises(schemas.DefinitionNotFoundError):
        schemas.type_hash('no_such_pkg/msg/Nothing')


@pytest.mark.parametrize('type_name, expected', [
    # Hashes rosbag2 (Jazzy) stored in its test bag for these types.
    ('rcl_interfaces/msg/Log',
     'RIHS01_e28ce254ca8abc06abf92773b74602cdbf116ed34fbaf294fb9f81da9f318eac'),
    ('rcl_interfaces/msg/ParameterEvent',
     'RIHS01_043e627780fcad87a22d225bc2a037361dba713fca6a6b9f4b869a5aa0393204'),
])
def test_type_hash(type_name, expected):
    assert schemas.type_hash(type_name) == expected
    assert schemas.type_hash(type_name.replace('/msg/', '/')) == expected


def test_type_names():
    assert split_type_name('sensor_msgs/msg/JointState') == ('sensor_msgs', 'JointState')
    assert split_type_name('sensor_msgs/JointState') == ('sensor_msgs', 'JointState')
    assert canonical_type_name('std_msgs/Float64') == 'std_msgs/msg/Float64'
    for bad in ('JointState', 'a/srv/B', 'a/msg/B/c', ''):
        with pytest.raises(ValueError):
            split_type_name(bad)
    cls = import_message_class('sensor_msgs/msg/JointState')
    assert cls.__name__ == 'JointState'
    assert type_name_of(cls()) == type_name_of(cls) == 'sensor_msgs/msg/JointState'
    with pytest.raises(AttributeError):
        import_message_class('std_msgs/msg/NoSuchMessage')
    with pytest.raises(ImportError):
        import_message_class('no_such_pkg/msg/Nothing')
    with pytest.raises(TypeError):
        type_name_of(3.0)
