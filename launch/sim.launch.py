"""
Start the sim node and RViz showing its TF and markers: ``ros2 launch sim sim.launch.py``.

Arguments: ``scene`` (a scene name or file, default ``default``), ``real_time_factor``,
``paused``, ``rviz`` (``false`` for the node alone), ``entity`` (an entity with joints, e.g.
``robot``, shown in RViz as a RobotModel from its ``robot_description``), ``viewer``
(``true``: MuJoCo's viewer window), ``web_view`` (a port: the browser view).
"""

from pathlib import Path
import tempfile

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from sim_node.ros.topics.rviz_config import with_robot_model

ARGUMENTS = {
    'scene': ('default', 'scene name (see get_available_worlds) or MJCF file'),
    'real_time_factor': ('1.0', '1 real time, 0 as fast as possible'),
    'paused': ('false', 'start paused'),
    'rviz': ('true', 'start RViz with rviz/sim.rviz (TF and markers)'),
    'entity': ('', 'an entity with joints (e.g. robot) to show in RViz as a RobotModel'),
    'viewer': ('false', "open MuJoCo's viewer window on the live world"),
    'web_view': ('0', 'serve the live world to a browser on this port (0: off)'),
}
#: Launch arguments that are not node parameters.
LAUNCH_ONLY = ('rviz', 'entity')


def _rviz(context):
    config = Path(get_package_share_directory('sim')) / 'rviz' / 'sim.rviz'
    entity = LaunchConfiguration('entity').perform(context)
    if entity:
        with tempfile.NamedTemporaryFile('w', prefix='sim-', suffix='.rviz',
                                         delete=False) as f:
            f.write(with_robot_model(config.read_text(), entity))
        config = Path(f.name)
    return [Node(package='rviz2', executable='rviz2', name='rviz2', output='screen',
                 arguments=['-d', str(config)], parameters=[{'use_sim_time': True}],
                 condition=IfCondition(LaunchConfiguration('rviz')))]


def generate_launch_description():
    config = {name: LaunchConfiguration(name) for name in ARGUMENTS}
    return LaunchDescription([
        *(DeclareLaunchArgument(name, default_value=default, description=text)
          for name, (default, text) in ARGUMENTS.items()),
        Node(package='sim', executable='node', name='sim', output='screen',
             parameters=[{'scene': config['scene'],
                          'real_time_factor': config['real_time_factor'],
                          'paused': config['paused'], 'viewer': config['viewer'],
                          'web_view': config['web_view']}]),
        OpaqueFunction(function=_rviz),
    ])
