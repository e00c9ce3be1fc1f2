"""Install script for the feed_axis_energy ament_python package.

The shipped configs (``config/``: machine and node parameter YAML, campaigns, example
programs) are installed twice, once for each way the package is found at run time
(``feed_axis_energy.paths``): as package data ``feed_axis_energy/config/`` inside the wheel
(``importlib.resources``; what ``pip install .`` gives) and, for ROS 2, under
``share/feed_axis_energy/config`` (the ament index; what colcon gives, beside ``package.xml``
and the launch file).
"""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'feed_axis_energy'
CONFIG_PATTERNS = ['*.yaml', 'programs/*.nc', 'campaigns/*.yaml']

# Runtime dependencies of the package itself (pins: requirements.txt, constraints.txt).
# zstandard and lz4 compress MCAP chunks (record/mcapstream.py); matplotlib draws the reports.
INSTALL_REQUIRES = ['numpy', 'scipy', 'PyYAML', 'rosbags', 'mcap', 'zstandard', 'lz4',
                    'matplotlib']
# The nodes need rclpy and the message packages. A ROS 2 install provides them (package.xml);
# without one, the `ros` extra brings the ros-* wheels that requirements.txt pins.
ROS_WHEELS = ['ros-rclpy[fastrtps]', 'ros-std-msgs', 'ros-builtin-interfaces',
              'ros-diagnostic-msgs', 'ros-rosgraph-msgs', 'ros-trajectory-msgs',
              'ros-lifecycle-msgs', 'ros-ament-index-python']

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']) + [PACKAGE + '.config'],
    # config/ is the package data directory feed_axis_energy/config of an installed package
    package_dir={PACKAGE + '.config': 'config'},
    package_data={PACKAGE + '.config': CONFIG_PATTERNS},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
        ('share/' + PACKAGE + '/config/programs', glob('config/programs/*.nc')),
        ('share/' + PACKAGE + '/config/campaigns', glob('config/campaigns/*.yaml')),
        ('share/' + PACKAGE + '/launch', glob('launch/*.launch.py')),
    ],
    install_requires=INSTALL_REQUIRES,
    # pyarrow: only simulate --parquet (a clear error without it)
    # cell: the OPC UA server and MQTT bridge of the machine cell (feed_axis_energy/bridge)
    extras_require={'ros': ROS_WHEELS, 'parquet': ['pyarrow'], 'cell': ['asyncua', 'paho-mqtt']},
    python_requires='>=3.10',
    zip_safe=False,
    maintainer='feed_axis_energy maintainers',
    maintainer_email='maintainers@feed-axis-energy.invalid',
    description='Virtual ball-screw feed axis: power and energy from an NC program.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'feed-axis-energy = feed_axis_energy.cli:main',
            'gcode_trajectory = feed_axis_energy.nodes.gcode_trajectory:main',
            'axis_dynamics = feed_axis_energy.nodes.axis_dynamics:main',
            'energy_estimator = feed_axis_energy.nodes.energy_estimator:main',
            'measured_replay = feed_axis_energy.nodes.measured_replay:main',
            'mcap_recorder = feed_axis_energy.nodes.mcap_recorder:main',
            'opcua_bridge = feed_axis_energy.nodes.opcua_bridge:main',
        ],
    },
)
