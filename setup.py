"""Ament_python packaging of `sim`: `ros2 run sim node` starts `<prefix>/lib/sim/node`."""

from glob import glob
import os

from setuptools import find_packages, setup

PACKAGE = 'sim'


def scene_data_files() -> list:
    """Install every file under scenes/ to share/sim/scenes, keeping sub-folders."""
    out = {}
    for path in glob('scenes/**/*', recursive=True):
        if os.path.isfile(path):
            out.setdefault(os.path.join('share', PACKAGE, os.path.dirname(path)), []).append(path)
    return sorted(out.items())


setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(include=['sim_node', 'sim_node.*', 'msg_adapters', 'msg_adapters.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/launch', glob('launch/*.launch.py')),
        ('share/' + PACKAGE + '/rviz', glob('rviz/*.rviz')),
    ] + scene_data_files(),
    package_data={'sim_node.ros.node': ['fastdds_profiles.xml']},
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='sim developers',
    maintainer_email='sim@example.com',
    description='MuJoCo simulator served as a ROS 2 node with simulation_interfaces services.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'node = sim_node.ros.node.entry:main',
            'spawn = sim_node.ros.client.spawn:main',
        ],
        'gymnasium.envs': [
            '__root__ = sim_node.gym.env:register_envs',
        ],
    },
)
