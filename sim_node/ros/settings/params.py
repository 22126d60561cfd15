"""
The node's ROS parameters.

Declared from the one table of :mod:`.parameter_table` (defaults from
:class:`~sim_node.core.config.WorldConfig` and ``PerceptionConfig``) with descriptors
(description, range, read-only where a change needs a restart).
"""

import dataclasses
import re
from typing import List

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter

from .parameter_table import DOUBLES, PARAMETERS, Spec, STRING_ARRAY
from ...core.base.checks import closest_hint
from ...core.base.config import PerceptionConfig, WorldConfig


@dataclasses.dataclass(frozen=True)
class Frames:
    """The node's frame names: the world body's (`world_frame`) and the prefix of every frame."""

    world: str = 'world'
    prefix: str = ''

    @property
    def out_world(self) -> str:
        """Return the world frame as published (after the prefix)."""
        return self.prefix + self.world

    def reference(self, frame_id: str) -> str:
        """'' for the world frame, else the entity whose frame a request's pose is given in."""
        if frame_id in ('', self.world, '/' + self.world, self.out_world):
            return ''
        return frame_id


def frames(node: Node) -> Frames:
    return Frames(node.get_parameter('world_frame').value,
                  node.get_parameter('frame_prefix').value)


def _descriptor(spec: Spec, scenes_dir: str) -> ParameterDescriptor:
    d = ParameterDescriptor(description=spec.description.format(scenes_dir=scenes_dir),
                            read_only=spec.read_only)
    if spec.limits is not None and isinstance(spec.default, float):
        d.floating_point_range = [FloatingPointRange(from_value=float(spec.limits[0]),
                                                     to_value=float(spec.limits[1]), step=0.0)]
    elif spec.limits is not None:
        d.integer_range = [IntegerRange(from_value=int(spec.limits[0]),
                                        to_value=int(spec.limits[1]), step=0)]
    return d


def integers_as_doubles(params: List[Parameter]) -> List[Parameter]:
    """
    Accept an integer value for a double parameter as that double.

    Nothing else changes (a string stays a string, and is refused as the wrong type).
    """
    return [Parameter(p.name, Parameter.Type.DOUBLE, float(p.value))
            if p.name in DOUBLES and p.type_ == Parameter.Type.INTEGER else p for p in params]


def string_list(node: Node, name: str) -> List[str]:
    """Return a string-array parameter declared without a default ([] when it was not given)."""
    try:
        return list(node.get_parameter(name).value or [])
    except ParameterUninitializedException:
        return []


def declare(node: Node, scenes_dir: str) -> None:
    """
    Declare every parameter of the node with its default.

    Integers given on the command line for double parameters are taken as doubles, at start-up and
    at run time.
    """
    overrides = getattr(node, '_parameter_overrides', {})  # rclpy keeps --ros-args -p here
    for p in integers_as_doubles(list(overrides.values())):
        overrides[p.name] = p
    node.add_pre_set_parameters_callback(integers_as_doubles)
    for spec in PARAMETERS:
        default = Parameter.Type.STRING_ARRAY if spec.default is STRING_ARRAY else spec.default
        node.declare_parameter(spec.name, default, _descriptor(spec, scenes_dir))
    unknown = sorted(n for n in overrides if not node.has_parameter(n))
    if unknown:  # rclpy drops them silently: a typo would go unnoticed
        names = list(node.get_parameters_by_prefix(''))  # every declared name
        node.get_logger().warning('; '.join(
            f'unknown parameter {n!r} ignored{closest_hint(n, names)}' for n in unknown))


def _with_article(word: str) -> str:
    return f"{'an' if word[:1] in 'aeiou' else 'a'} {word}"


def parameter_error(exc: Exception) -> str:
    """Say in one line which parameter a start-up value was refused for, and what it takes."""
    text = str(exc)
    m = re.match(r"Trying to set parameter '(?P<name>[^']*)' to '(?P<value>.*)' of type "
                 r"'(?P<got>\w+)', expecting type '(?:Type\.)?(?P<want>\w+)'", text, re.S)
    if m:
        got, want = (_with_article(m[k].lower().replace('_', ' ')) for k in ('got', 'want'))
        return f"parameter {m['name']}: {m['value']!r} is {got}, but it takes {want}"
    m = re.match(r'.*Reason: (?P<reason>.*): (?P<name>[^:]+)$', text, re.S)
    if m:
        r = re.match(r'.*out of range Min: (?P<lo>\S+), Max: (?P<hi>\S+), value: (?P<v>.+)$',
                     m['reason'], re.S)
        if r:
            return (f"parameter {m['name']}: {r['v']} is out of its range, "
                    f"{r['lo']} to {r['hi']}")
        return f"parameter {m['name']}: {' '.join(m['reason'].split())}"
    return ' '.join(text.split())


def perception_config(node: Node) -> PerceptionConfig:
    """Return the cameras and sensors configuration of the node's parameters."""
    names = [f.name for f in dataclasses.fields(PerceptionConfig)]
    values = {n: node.get_parameter(n).value for n in names}
    values['cameras'] = tuple(values['cameras'])
    values['lidar_sites'] = tuple(values['lidar_sites'])
    return PerceptionConfig(**values)


def world_config(node: Node) -> WorldConfig:
    """Return the configuration the node's current parameters describe."""
    def p(name: str):
        return node.get_parameter(name).value
    return WorldConfig(
        real_time_factor=p('real_time_factor'), paused=p('paused'), timestep=p('timestep'),
        max_steps=p('max_steps'), max_sim_time=p('max_sim_time'),
        # Twice the fastest publisher, so that every publishing tick finds a new snapshot.
        snapshot_rate_hz=2 * max(p('tf_rate_hz'), p('joint_states_rate_hz')),
        kp=p('kp'), kd=p('kd'), allow_interpenetration=p('allow_interpenetration'),
        max_bodies=p('max_bodies'), world_extent=p('world_extent'),
        divergence_policy=p('divergence_policy'), mesh_cache_mb=p('mesh_cache_mb'),
        mesh_cache_keep_sec=p('mesh_cache_keep_sec'), mesh_cache_keep_mb=p('mesh_cache_keep_mb'),
        casters_roll=p('casters_roll'), mesh_decomposition=p('mesh_decomposition'),
        mesh_decomposition_threshold=p('mesh_decomposition_threshold'),
        contact_entities=tuple(string_list(node, 'contact_entities')),
        contact_rate_hz=p('contact_rate_hz'))
