"""Install script for the feed_axis_energy ament_python package."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'feed_axis_energy'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
        ('share/' + PACKAGE + '/config/programs', glob('config/programs/*.nc')),
        ('share/' + PACKAGE + '/launch', glob('launch/*.launch.py')),
    ],
    package_data={PACKAGE: ['data/*.yaml', 'data/*.nc']},
    install_requires=['setuptools', 'numpy', 'scipy', 'pyyaml', 'rosbags', 'mcap'],
    zip_safe=True,
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
        ],
    },
)
