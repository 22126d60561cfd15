"""
Start the sim node and RViz showing its TF and markers: ``ros2 launch sim sim.launch.py``.

Arguments: ``scene`` (a scene name or file, default ``default``), ``real_time_factor``,
``paused``, ``rviz`` (``false`` for the node alone).
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

ARGUMENTS = {
    'scene': ('default', 'scene name (see get_available_worlds) or MJCF file'),
    'real_time_factor': ('1.0', '1 real time, 0 as fast as possible'),
    'paused': ('false', 'start paused'),
    'rviz': ('true', 'start RViz with rviz/sim.rviz (TF and markers)'),
}


def generate_launch_description():
    config = {name: LaunchConfiguration(name) for name in ARGUMENTS}
    return LaunchDescription([
        *(DeclareLaunchArgument(name, default_value=default, description=text)
          for name, (default, text) in ARGUMENTS.items()),
        Node(package='sim', executable='node', name='sim', output='screen',
             parameters=[{'scene': config['scene'],
                          'real_time_factor': config['real_time_factor'],
                          'paused': config['paused']}]),
        Node(package='rviz2', executable='rviz2', name='rviz2', output='screen',
             arguments=['-d', PathJoinSubstitution([FindPackageShare('sim'), 'rviz',
                                                    'sim.rviz'])],
             parameters=[{'use_sim_time': True}],
             condition=IfCondition(config['rviz'])),
    ])
