"""
The gz-sim systems an SDF file names, by what they are here.

A ``<plugin filename="gz-sim-diff-drive-system" name="gz::sim::systems::DiffDrive">`` (or
``libgz-sim-...-system.so``, ``ignition-gazebo-...``, ``ignition::gazebo::systems::...``) is
known by its system name (:func:`system_name`: ``DiffDrive``). World systems that only make
Gazebo do what this simulator always does (its physics, its scene broadcast to the GUI, its
user commands, its sensors and the systems that feed them) are accepted silently
(:data:`SILENT`); the model systems this simulator runs are :data:`RUN` (their laws:
:mod:`sim_node.core.control`); any other is named once in a warning and on /diagnostics
(:func:`world_systems`, :func:`model_systems`).
"""

import re
from typing import Iterable
import xml.etree.ElementTree as ET

#: Systems whose work this simulator does anyway.
SILENT = frozenset({
    'Physics', 'MujocoPhysics', 'SceneBroadcaster', 'UserCommands', 'Sensors', 'Imu',
    'Contact', 'ForceTorque', 'Altimeter', 'Magnetometer', 'NavSat', 'AirPressure',
    'LogicalCamera'})
#: Model systems this simulator runs (see the module docstring).
RUN = frozenset({
    'DiffDrive', 'AckermannSteering', 'JointPositionController', 'JointController',
    'JointStatePublisher', 'JointTrajectoryController', 'PosePublisher',
    'GazeboSimROS2ControlPlugin', 'IgnitionROS2ControlPlugin', 'gz_ros2_control',
    'OdometryPublisher'})
_PREFIXES = ('libgz-sim-', 'gz-sim-', 'libignition-gazebo-', 'ignition-gazebo-')


def system_name(plugin: ET.Element) -> str:
    """Return the system a ``<plugin>`` names (``DiffDrive``), from its name or file."""
    name = (plugin.get('name') or '').strip()
    if '::' in name:
        return name.rsplit('::', 1)[-1]
    filename = (plugin.get('filename') or '').strip()
    base = filename.rsplit('/', 1)[-1]
    base = re.sub(r'\.so(\.\d+)*$', '', base)
    if 'ros2_control' in base:
        return 'gz_ros2_control'
    for prefix in _PREFIXES:
        if base.startswith(prefix):
            base = re.sub(r'^\d+-', '', base[len(prefix):])
            break
    base = re.sub(r'-system$', '', base)
    return ''.join(p.capitalize() for p in re.split(r'[-_]', base) if p) or name or filename


def _unknown(plugins: Iterable[ET.Element], known: frozenset) -> list:
    out = []
    for p in plugins:
        name = system_name(p)
        if name not in known and name not in out:
            out.append(name)
    return out


def world_systems(world: ET.Element) -> list:
    """Return the world plugins this simulator neither runs nor needs: named in a warning."""
    return _unknown(world.findall('plugin'), SILENT | RUN)


def model_systems(model: ET.Element) -> list:
    """Return a model's plugins that this simulator does not run (not its sensors')."""
    inside = {id(p) for s in model.iter('sensor') for p in s.iter('plugin')}
    return _unknown((p for p in model.iter('plugin') if id(p) not in inside), SILENT | RUN)
