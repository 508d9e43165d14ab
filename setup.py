"""Build script for drill_twin (ament_python layout, also installable with pip)."""
from glob import glob

from setuptools import find_packages, setup

package_name = 'drill_twin'

# What an ament prefix holds besides the Python package; scripts/link_ament_files.py
# places the same files into the venv after an editable install (make setup).
DATA_FILES = [
    ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
    ('share/' + package_name, ['package.xml']),
    ('share/' + package_name + '/config', sorted(glob('config/*.yaml'))),
    ('share/' + package_name + '/launch', sorted(glob('launch/*.launch.py'))),
    # `ros2 run drill_twin twin` looks for an executable in lib/<package>/.
    ('lib/' + package_name, ['scripts/twin']),
]

if __name__ == '__main__':
    setup(
        name=package_name,
        version='0.1.0',
        packages=find_packages(exclude=['test', 'test.*']),
        data_files=DATA_FILES,
        python_requires='>=3.10',
        install_requires=[
            'setuptools',
            'numpy>=1.25',            # Generator.spawn (the filter's resampling stream)
            'scipy>=1.10',
            'PyYAML>=6.0',
            'matplotlib>=3.7',
            'mcap>=1.1',
            'zstandard>=0.21',
            'mcap-ros2-support>=0.5',
            'rerun-sdk>=0.41',
            'dask[distributed]>=2024.1',
            'threadpoolctl>=3.1',
            'numba>=0.59',
        ],
        extras_require={
            # rclpy and the message packages come from ROS on a ROS machine; without ROS
            # they come from PyPI's ROS wheels.
            'ros': ['ros-jazzy-rclpy[fastrtps]', 'ros-jazzy-common-interfaces'],
            'test': ['pytest>=7', 'pytest-timeout', 'pytest-xdist>=3', 'sympy>=1.12', 'wheel',
                     'pandas', 'hypothesis>=6',
                     'rosbags>=0.10', 'flake8>=7', 'flake8-docstrings>=1.7', 'pydocstyle>=6.3',
                     'import-linter>=2.1'],
        },
        zip_safe=True,
        maintainer='drill_twin developers',
        maintainer_email='drill-twin@example.com',
        description='ROS 2 digital twin of a drill string (Ritto, Soize & Sampaio 2009).',
        license='Apache-2.0',
        entry_points={
            'console_scripts': [
                'drill-twin = drill_twin.cli.main:main',
            ],
        },
    )
