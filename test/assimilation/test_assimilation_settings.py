"""The assimilation: section: defaults, overrides, one-line errors naming the key."""
import pytest

from drill_twin.assimilation.settings import load_assimilation, model_overrides
from drill_twin.config.loader import ConfigError


def test_the_shipped_file_loads():
    settings = load_assimilation()
    assert settings.filter.method in ('etkf', 'enkf')
    assert settings.sensors.downhole.delay_s > 0
    assert settings.sensor_of('top_torque') is settings.sensors.top_drive


@pytest.mark.parametrize('item, key', [
    ('assimilation.filter.members=1', 'assimilation.filter.members'),
    ('assimilation.filter.inflation=0.9', 'assimilation.filter.inflation'),
    ('assimilation.filter.relaxation=1', 'assimilation.filter.relaxation'),
    ('assimilation.filter.measurements=[torque]', 'assimilation.filter.measurements'),
    ('assimilation.channels.top_torque.noise_std=-1',
     'assimilation.channels.top_torque.noise_std'),
    ('assimilation.sensors.downhole.delay_s=-2', 'assimilation.sensors.downhole.delay_s'),
    ('assimilation.sensors.hook.topic=rig/hook', 'assimilation.sensors.hook.topic'),
    ('assimilation.filter.method=ukf', 'assimilation.filter.method'),
    ('assimilation.filter.hole_rate_window_s=-30', 'assimilation.filter.hole_rate_window_s'),
    ('assimilation.filter.localisation=blocks', 'assimilation.filter.localisation'),
    ('assimilation.filter.hole_rate_prediction=law',
     'assimilation.filter.hole_rate_prediction'),
    ('assimilation.filter.increment_duration_s=-0.05',
     'assimilation.filter.increment_duration_s'),
    ('assimilation.filter.increment_duration_s=1.0',        # the analysis interval (1 Hz)
     'assimilation.filter.increment_duration_s'),
    ('assimilation.filter.increment_duration_s=.nan', 'assimilation.filter.increment_duration_s'),
])
def test_a_bad_value_is_one_line_naming_the_key(item, key):
    with pytest.raises(ConfigError) as error:
        load_assimilation(None, [item])
    message = str(error.value)
    assert '\n' not in message and key in message and message.startswith('--set')


def test_the_hole_rate_needs_the_block_position():
    assert load_assimilation(None, ['assimilation.filter.hole_rate_window_s=30']
                             ).filter.hole_rate_window_s == 30
    with pytest.raises(ConfigError, match='hole_rate_window_s: needs block_position'):
        load_assimilation(None, ['assimilation.filter.hole_rate_window_s=30',
                                 'assimilation.filter.measurements=[top_torque]'])


def test_an_unknown_key_is_refused():
    with pytest.raises(ConfigError, match='assimilation.rig.colour: unknown key'):
        load_assimilation(None, ['assimilation.rig.colour=1'])


def test_a_file_overrides_the_defaults_and_is_blamed(tmp_path):
    path = tmp_path / 'a.yaml'
    path.write_text('assimilation:\n  filter:\n    members: 7\n')
    assert load_assimilation(path).filter.members == 7
    path.write_text('assimilation:\n  filter:\n    members: 0\n')
    with pytest.raises(ConfigError, match=f'^{path}: assimilation.filter.members'):
        load_assimilation(path)
    path.write_text('filter:\n  members: 3\n')
    with pytest.raises(ConfigError, match='assimilation'):
        load_assimilation(path)


def test_the_model_keeps_its_own_overrides():
    assert model_overrides(['assimilation.filter.members=3', 'bit_rock.a1_m_per_s=1e-3']) == [
        'bit_rock.a1_m_per_s=1e-3']


def test_the_assimilation_core_never_imports_rclpy():
    import os
    import subprocess
    import sys
    from pathlib import Path

    code = ('import sys\n'
            'import drill_twin.assimilation.filter, drill_twin.assimilation.offline\n'
            'import drill_twin.assimilation.rig_emulator, drill_twin.assimilation.steady_law\n'
            'import drill_twin.cli.rig, drill_twin.cli.assimilate, drill_twin.cli.rig_files\n'
            'assert "rclpy" not in sys.modules, "the assimilation core imported rclpy"\n')
    root = str(Path(__file__).resolve().parents[2])
    subprocess.run([sys.executable, '-c', code], check=True, timeout=120,
                   env=dict(os.environ, PYTHONPATH=root))
