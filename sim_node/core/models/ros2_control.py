"""
What a URDF's ``<ros2_control>`` block and its Gazebo control plugin declare, read and checked.

A robot made for Gazebo and ros2_control carries (after xacro):

* ``<ros2_control name=... type="system">`` with ``<hardware><plugin>`` (Gazebo's
  ``gz_ros2_control/GazeboSimSystem``, ``ign_ros2_control/IgnitionSystem``, classic
  ``gazebo_ros2_control/GazeboSystem``, ``mock_components/GenericSystem``, or
  ``topic_based_ros2_control/TopicBasedSystem``), its joints with their
  ``<command_interface>`` (``min``/``max`` params) and ``<state_interface>`` (an
  ``initial_value`` param), and its sensors with their state interfaces;
* ``<gazebo><plugin filename="gz_ros2_control-system">`` (or classic
  ``libgazebo_ros2_control.so``) with the controllers YAML in ``<parameters>`` (one or more),
  a ``<ros><namespace>`` and ``<remapping>`` rules, a ``<controller_manager_name>``,
  ``<hold_joints>`` and ``<position_proportional_gain>``.

:func:`read` returns a :class:`Ros2Control` of it, with the robot's own names; the node serves
its controller manager (:mod:`sim_node.ros.control.controller_manager`). ROS-free.
"""

from dataclasses import dataclass, field, replace
import logging
import math
import re
import time
from typing import Optional
from xml.etree import ElementTree as ET

#: Hardware plugins whose joints this simulator drives itself (a controller manager here).
SIMULATED = ('gz_ros2_control/GazeboSimSystem', 'ign_ros2_control/IgnitionSystem',
             'gazebo_ros2_control/GazeboSystem', 'mock_components/GenericSystem')
#: Hardware plugins whose joints a controller manager elsewhere drives by topics.
TOPIC_BASED = ('topic_based_ros2_control/TopicBasedSystem',
               'joint_state_topic_hardware_interface/JointStateTopicSystem')
#: Gazebo control plugins (their file names, without ``lib`` and ``.so``).
CONTROL_PLUGINS = ('gz_ros2_control-system', 'ign_ros2_control-system', 'gazebo_ros2_control')
INTERFACES = ('position', 'velocity', 'effort', 'acceleration')
#: The fastest velocity command a joint whose URDF gives no ``<limit velocity>`` takes (rad/s
#: or m/s; about 950 rpm, 30 m/s on a wheel 0.3 m in radius). A URDF's revolute and prismatic
#: joints must give one; its continuous joints (wheels) may not. Held at 1,000 rad/s, a car's
#: wheels (gz_ros2_control's Ackermann demo, no effort limit) fling it 100 m in 0.8 s and its
#: physics diverges; at this it flies but keeps stepping. A robot whose joints go faster
#: declares its ``<limit velocity>``.
MAX_COMMAND_SPEED = 100.0
#: Seconds between two warnings of one joint's capped velocity commands (a controller sends
#: one at every update).
CAP_WARNING_PERIOD = 10.0

#: gz_ros2_control's ``<position_proportional_gain>`` when its plugin gives none.
DEFAULT_POSITION_GAIN = 0.1
#: One side of a ``<remapping>`` rule: a topic or service name, relative, absolute or private
#: (no ``__`` in it, which ROS reserves).
_NAME = re.compile(r'^(~/|/)?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*$')

log = logging.getLogger(__name__)
_warned: dict = {}  # joint name -> time.monotonic() of its last capping warning


@dataclass(frozen=True)
class HardwareJoint:
    """
    A joint of a ``<ros2_control>`` block.

    :param command: command interface -> (min, max), None where not given.
    :param state: its state interfaces, in order.
    :param initial: state interface -> its ``initial_value``.
    :param speed: the URDF joint's ``<limit velocity>`` (None: none given).
    """

    name: str
    command: dict = field(default_factory=dict)
    state: tuple = ()
    initial: dict = field(default_factory=dict)
    speed: Optional[float] = None

    def within(self, interface: str, value: float) -> float:
        """
        Return `value` within the interface's ``min`` and ``max`` (where declared).

        A velocity is also kept within the URDF's ``<limit velocity>`` (as ros2_control's
        joint limits keep it), or :data:`MAX_COMMAND_SPEED` where none is given, with a
        warning naming the joint and the value asked (at most one per joint every
        :data:`CAP_WARNING_PERIOD` seconds).
        """
        lo, hi = self.command.get(interface, (None, None))
        out = value if lo is None else max(value, lo)
        out = out if hi is None else min(out, hi)
        if interface == 'velocity':
            bound = self.speed or MAX_COMMAND_SPEED
            if not abs(out) <= bound:  # NaN too: a controller's command is never NaN here
                out = math.copysign(bound, out) if not math.isnan(out) else 0.0
                now = time.monotonic()
                if now - _warned.get(self.name, -math.inf) >= CAP_WARNING_PERIOD:
                    _warned[self.name] = now
                    log.warning('joint %r: a velocity command of %.6g is capped at %.6g (%s)',
                                self.name, value, out, 'its URDF <limit velocity>'
                                if self.speed else 'no URDF <limit velocity>: the most any '
                                'joint takes')
        return out


@dataclass(frozen=True)
class HardwareComponent:
    """One ``<ros2_control>`` block: a hardware component and what it exports."""

    name: str
    kind: str  # 'system', 'actuator', 'sensor'
    plugin: str
    joints: tuple = ()  # HardwareJoint
    sensors: dict = field(default_factory=dict)  # sensor name -> its state interfaces
    params: dict = field(default_factory=dict)  # <hardware><param name=...>


@dataclass(frozen=True)
class Ros2Control:
    """
    A robot's ros2_control declaration, with its own (URDF) names.

    :param parameters: the controllers YAML files its Gazebo plugin names, in order.
    :param namespace: the plugin's ``<ros><namespace>`` ('' : none); a spawn's namespace
        replaces it.
    :param manager: the controller manager's node name (``controller_manager``).
    :param hold_joints: the plugin's ``<hold_joints>`` (default true): the joints no active
        controller claims are held still, as gz_ros2_control holds them
        (:class:`~sim_node.core.control.laws.HoldLaw`); false: they are left free.
    :param position_gain: the plugin's ``<position_proportional_gain>`` (default 0.1): a
        position interface moves its joint at this times the update rate times its error
        (:mod:`~sim_node.core.control.interfaces`).
    :param update_rate: its controller manager's ``update_rate`` as its YAML gives it, where
        the node may read the YAML (None: not read; the manager's default is taken).
    :param remappings: the plugin's ``<ros><remapping>`` rules (``from:=to``), in order: the
        controller manager's and its controllers' names remapped as ROS remaps a node's.
    :param spawn: which spawn it came with (a robot spawned again is another robot, with
        controllers of its own, even when nothing was seen in between).
    """

    components: tuple = ()  # HardwareComponent
    parameters: tuple = ()
    namespace: str = ''
    manager: str = 'controller_manager'
    spawn: int = 0
    hold_joints: bool = True
    remappings: tuple = ()
    position_gain: float = DEFAULT_POSITION_GAIN
    update_rate: Optional[float] = None

    @property
    def simulated(self) -> bool:
        """Whether a controller manager here drives its joints (Gazebo's or mock hardware)."""
        return any(c.plugin in SIMULATED for c in self.components)

    @property
    def topic_based(self) -> Optional[HardwareComponent]:
        """Its TopicBasedSystem component, whose joints come and go by topics, if any."""
        return next((c for c in self.components if c.plugin in TOPIC_BASED), None)

    def joints(self) -> dict:
        """Return joint name -> :class:`HardwareJoint` over every component."""
        return {j.name: j for c in self.components for j in c.joints}

    def with_speeds(self, limits: dict) -> 'Ros2Control':
        """Return it with its joints' URDF ``<limit velocity>`` (joint -> {'velocity': v})."""
        def joint(j: HardwareJoint) -> HardwareJoint:
            speed = abs((limits.get(j.name) or {}).get('velocity') or 0.0)
            return replace(j, speed=speed if 0 < speed < math.inf else None)
        return replace(self, components=tuple(
            replace(c, joints=tuple(joint(j) for j in c.joints)) for c in self.components))


def read(extensions: list) -> Optional[Ros2Control]:
    """Return what the extension elements declare for ros2_control, or None."""
    blocks = [e for e in extensions if e.tag == 'ros2_control']
    if not blocks:
        return None
    components = tuple(_component(b) for b in blocks)
    parameters, namespace, manager, hold, remaps = [], '', 'controller_manager', True, []
    gain = DEFAULT_POSITION_GAIN
    for ext in extensions:
        if ext.tag != 'gazebo':
            continue
        for plugin in ext.iter('plugin'):
            filename = (plugin.get('filename') or '').strip()
            base = filename[3:] if filename.startswith('lib') else filename
            base = base[:-3] if base.endswith('.so') else base
            if base not in CONTROL_PLUGINS:
                continue
            parameters += [(p.text or '').strip() for p in plugin.findall('parameters')
                           if (p.text or '').strip()]
            namespace = (plugin.findtext('ros/namespace') or namespace).strip().strip('/')
            manager = (plugin.findtext('controller_manager_name') or manager).strip()
            hold = _flag(plugin, 'hold_joints', hold)
            remaps += [r for r in (_remapping(e.text) for e in plugin.findall('ros/remapping'))
                       if r]
            gain = _gain(plugin.findtext('position_proportional_gain'), gain)
    return Ros2Control(components=components, parameters=tuple(parameters),
                       namespace=namespace, manager=manager.strip('/') or 'controller_manager',
                       hold_joints=hold, remappings=tuple(remaps), position_gain=gain)


def _gain(text: Optional[str], default: float) -> float:
    """Return a ``<position_proportional_gain>``: a positive number, else `default`, said."""
    if text is None:
        return default
    value = _float(text)
    if value is not None and value > 0:
        return value
    log.warning('gz_ros2_control plugin: <position_proportional_gain> %r is not a positive '
                'number; %g is used', text, default)
    return default


def _remapping(text: Optional[str]) -> str:
    """
    Return a ``<remapping>`` rule as ROS takes it (``from:=to``), or '' with a warning.

    Topic and service names only: a rule of a node's name or namespace (``__node``,
    ``__ns``), or one ROS would refuse, is left out (ROS would refuse to start the node).
    """
    rule = (text or '').strip()
    sides = rule.split(':=')
    if len(sides) == 2 and all(_NAME.match(side.strip()) and '__' not in side for side in sides):
        return ':='.join(side.strip() for side in sides)
    log.warning('gz_ros2_control plugin: <remapping> %r is not a rule of topic or service names '
                '(from:=to); left out', text)
    return ''


def _flag(plugin: ET.Element, tag: str, default: bool) -> bool:
    """Return a plugin's boolean child as sdformat reads one; a value it refuses: `default`."""
    text = plugin.findtext(tag)
    if text is None:
        return default
    value = text.strip().lower()
    if value in ('true', '1'):
        return True
    if value in ('false', '0'):
        return False
    log.warning('gz_ros2_control plugin: <%s> %r is not true or false; %s is used', tag,
                text, str(default).lower())
    return default


def _component(block: ET.Element) -> HardwareComponent:
    hardware = block.find('hardware')
    plugin = (hardware.findtext('plugin') if hardware is not None else '') or ''
    params = {p.get('name', ''): (p.text or '').strip()
              for p in (hardware.findall('param') if hardware is not None else [])}
    joints = []
    for joint in block.findall('joint'):
        command = {}
        for ci in joint.findall('command_interface'):
            limits = {p.get('name'): _float(p.text) for p in ci.findall('param')}
            command[(ci.get('name') or '').strip()] = (limits.get('min'), limits.get('max'))
        state, initial = [], {}
        for si in joint.findall('state_interface'):
            name = (si.get('name') or '').strip()
            state.append(name)
            for p in si.findall('param'):
                value = _float(p.text)
                if p.get('name') == 'initial_value' and value is not None:
                    initial[name] = value
        joints.append(HardwareJoint(name=joint.get('name', ''), command=command,
                                    state=tuple(state), initial=initial))
    sensors = {s.get('name', ''): tuple((i.get('name') or '').strip()
                                        for i in s.findall('state_interface'))
               for s in block.findall('sensor')}
    return HardwareComponent(name=block.get('name', ''), kind=(block.get('type') or 'system'),
                             plugin=plugin.strip(), joints=tuple(joints), sensors=sensors,
                             params=params)


def _float(text: Optional[str]) -> Optional[float]:
    try:
        value = float((text or '').strip())
    except ValueError:
        return None
    return value if math.isfinite(value) else None
