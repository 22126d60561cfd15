"""
Spawn a robot from its URDF the ROS way: ``ros2 launch sim spawn_robot.launch.py urdf:=<file>``.

robot_state_publisher publishes the description on ``robot_description`` (transient local), as
in any ROS robot bring-up, and ``sim spawn`` spawns it from that topic into the running
simulator (``ros2 run sim node`` or ``sim.launch.py``), as Gazebo's ``create -topic`` does.
Arguments: ``urdf`` (a URDF file), ``name``, ``x``, ``y``, ``z``, ``Y`` (yaw, rad).
"""

from pathlib import Path

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

ARGUMENTS = {'urdf': ('', 'the robot description (a URDF file)'), 'name': ('robot', ''),
             'x': ('0.0', ''), 'y': ('0.0', ''), 'z': ('0.0', ''), 'Y': ('0.0', 'yaw (rad)')}


def _nodes(context):
    value = {name: LaunchConfiguration(name).perform(context) for name in ARGUMENTS}
    description = Path(value['urdf']).expanduser().read_text()
    spawn = ['-topic', 'robot_description', '-name', value['name']]
    for axis in ('x', 'y', 'z', 'Y'):
        spawn += [f'-{axis}', value[axis]]
    return [Node(package='robot_state_publisher', executable='robot_state_publisher',
                 output='screen', parameters=[{'robot_description': description}]),
            Node(package='sim', executable='spawn', output='screen', arguments=spawn)]


def generate_launch_description():
    return LaunchDescription([
        *(DeclareLaunchArgument(name, default_value=default, description=text)
          for name, (default, text) in ARGUMENTS.items()),
        OpaqueFunction(function=_nodes),
    ])
