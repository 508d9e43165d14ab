"""Launch the drill_twin node with its shipped parameters (``ros2 launch drill_twin
twin.launch.py``).

Arguments: ``params_file`` (default: the installed config/twin.yaml), ``model_config`` (a model
configuration YAML; empty for the built-in paper configuration), ``use_sim_time`` (follow an
external /clock, e.g. a bag player), ``log_dir`` (where the run's bag goes).
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    share = get_package_share_directory('drill_twin')
    arguments = [
        DeclareLaunchArgument('params_file', default_value=os.path.join(share, 'config',
                                                                        'twin.yaml'),
                              description='node parameters (drill_twin: ros__parameters:)'),
        DeclareLaunchArgument('model_config', default_value='',
                              description='model configuration YAML (empty: the paper)'),
        DeclareLaunchArgument('use_sim_time', default_value='false',
                              description='follow /clock instead of the wall clock'),
        DeclareLaunchArgument('log_dir', default_value='runs',
                              description='directory of the run logs'),
    ]
    twin = Node(
        package='drill_twin',
        executable='twin',
        name='drill_twin',
        output='screen',
        emulate_tty=True,
        parameters=[LaunchConfiguration('params_file'),
                    {'model_config': LaunchConfiguration('model_config'),
                     'use_sim_time': LaunchConfiguration('use_sim_time'),
                     'log_dir': LaunchConfiguration('log_dir')}],
    )
    return LaunchDescription([*arguments, twin])
