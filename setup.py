"""ament_python package: colcon build + ros2 run on a ROS 2 Jazzy install, pip in a venv here."""
from glob import glob

from setuptools import find_packages, setup

package_name = 'saw_ros'
NODES = ('simulator', 'camera', 'vision', 'comparison', 'recorder', 'player', 'video_source',
         'speed_controller', 'foxglove_bridge')

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['tests', 'tests.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/msg_config', glob('msg_config/*')),
        # Where `ros2 pkg prefix saw_ros` users look (docs/ros.md): the launch file, the URDF
        # and the viewers' layouts. scripts/bootstrap.sh mirrors this in the venv.
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
        ('share/' + package_name + '/urdf', ['urdf/saw.urdf']),
        ('share/' + package_name + '/viewers', ['docs/saw_ros.rviz', 'docs/foxglove_layout.json']),
    ],
    install_requires=['setuptools'],
    # colcon test runs pytest only for a package that declares it as a test requirement
    # (colcon-core: tests_require or extras_require['test']); otherwise it falls back to
    # unittest, which finds none of our pytest tests and reports OK.
    extras_require={'test': ['pytest', 'pytest-timeout']},
    zip_safe=True,
    maintainer='saw_ros developers',
    maintainer_email='saw_ros@example.com',
    description='SAW wave robot between flexible surfaces: simulator, vision, comparison, bags',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [f'{name} = saw_ros.ros.nodes.{name}:main' for name in NODES]
        + ['saw-ros = saw_ros.cli.main:main'],
    },
)
