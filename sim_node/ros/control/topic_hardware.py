"""
The topic contract of ``topic_based_ros2_control``, for a controller manager run beside `sim`.

A spawned URDF whose ``<ros2_control>`` hardware is ``topic_based_ros2_control/TopicBasedSystem``
(or ``joint_state_topic_hardware_interface/JointStateTopicSystem``) is driven by the real
controller_manager elsewhere, through two sensor_msgs/JointState topics its ``<hardware>``
params name (relative ones under the robot's namespace):

* ``joint_states_topic`` (default ``/robot_joint_states``): published here at
  :data:`STATES_HZ` of simulated time, the block's joints under their URDF names, position,
  velocity and effort, stamped with simulated time;
* ``joint_commands_topic`` (default ``/robot_joint_command``): taken here as the plugin sends
  it: every joint named, and per command interface an array holding the values of the joints
  that have that interface, in the names' order (shorter than the names when joints differ).
  A NaN is a command not written yet (the plugin sends NaN until a controller writes) and is
  left out; a message whose arrays do not fit the names and interfaces is refused, its reason
  logged and put on /diagnostics.
"""

import math

from msg_adapters import convert
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from sensor_msgs.msg import JointState

from ...core.base.errors import SimError

#: Joint states per simulated second.
STATES_HZ = 100.0
INTERFACES = ('position', 'velocity', 'effort')


class TopicHardware:
    """One robot's joint command and joint state topics (see the module docstring)."""

    def __init__(self, host, node, entity: str, control):
        self.host, self.node, self.entity, self.control = host, node, entity, control
        hw = control.topic_based
        ns = f'/{control.namespace}' if control.namespace else ''
        commands = hw.params.get('joint_commands_topic') or '/robot_joint_command'
        states = hw.params.get('joint_states_topic') or '/robot_joint_states'
        self.commands_topic = commands if commands.startswith('/') else f'{ns}/{commands}'
        self.joints = list(hw.joints)
        self.key = f'{entity}:topic_based'
        self.pub = node.create_publisher(
            JointState, states if states.startswith('/') else f'{ns}/{states}', 10,
            event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))
        self.sub = node.create_subscription(
            JointState, self.commands_topic, self._on_command, 10,
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))
        host.sample(self.key, [f'{entity}/{j.name}' for j in self.joints], STATES_HZ)

    def close(self) -> None:
        self.host.sample(self.key, [], 0.0)
        self.node.destroy_subscription(self.sub)
        self.node.destroy_publisher(self.pub)

    def on_sample(self, sample) -> None:
        msg = JointState(name=[j.name for j in self.joints],
                         position=[float(x) for x in sample.position],
                         velocity=[float(x) for x in sample.velocity],
                         effort=[float(x) for x in sample.effort])
        msg.header.stamp = convert.stamp(sample.time)
        self.pub.publish(msg)

    def _on_command(self, msg: JointState) -> None:
        joints = {j.name: j for j in self.joints}
        names = list(msg.name)
        unknown = [n for n in names if n not in joints]
        arrays = {'position': list(msg.position), 'velocity': list(msg.velocity),
                  'effort': list(msg.effort)}
        wanted = {i: [n for n in names if n in joints and i in joints[n].command]
                  for i in INTERFACES}
        odd = [f'{len(arrays[i])} {i} values for {len(wanted[i])} joints with a {i} '
               f'interface' for i in INTERFACES if arrays[i] and len(arrays[i]) != len(wanted[i])]
        if unknown or odd:
            why = (f'joints {unknown} are not in its <ros2_control> block' if unknown
                   else '; '.join(odd))
            self.host.refused(self.commands_topic, 'joint command', why, names)
            return
        for interface in INTERFACES:
            pairs = [(n, v) for n, v in zip(wanted[interface], arrays[interface])
                     if math.isfinite(v)]
            if not pairs:
                continue
            values = [joints[n].within(interface, v) for n, v in pairs]
            try:
                self.host.session.require().world.command(
                    [f'{self.entity}/{n}' for n, _ in pairs], values, interface)
            except SimError as exc:
                self.host.refused(self.commands_topic, 'joint command', str(exc), names)
