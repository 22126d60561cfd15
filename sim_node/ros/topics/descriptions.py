"""
``<entity>/robot_description``: a URDF for every entity with joints, for RViz and MoveIt.

std_msgs/String, reliable and transient local (as robot_state_publisher offers it), depth 1: a
late subscriber gets the description at once. Made when the entity comes, sent again when its
description changes (a new mass, a welded part), removed when it goes. The text comes from
:meth:`~sim_node.core.world.World.robot_description` (a spawned URDF as given, otherwise written
from the compiled model, meshes as STL files under ``robot_description_mesh_dir``), built on the
node's model thread, never on the physics'.
"""

import os
from pathlib import Path
import threading
from typing import Optional

from msg_adapters.perception import interface_base
from rclpy.event_handler import PublisherEventCallbacks
from std_msgs.msg import String

from ..settings.qos import LATCHED_QOS
from ...core.base.errors import SimError
from ...core.base.records import ModelInfo, Snapshot
from ...session import Loaded, Session

DESCRIPTION_QOS = LATCHED_QOS


def default_mesh_dir() -> Path:
    """Return ``$XDG_CACHE_HOME/sim/meshes``, else ``~/.cache/sim/meshes``."""
    cache = os.environ.get('XDG_CACHE_HOME') or str(Path.home() / '.cache')
    return Path(cache) / 'sim' / 'meshes'


def described_entities(info: ModelInfo) -> list:
    """Return the entities that have a description: robots and spawned URDFs."""
    return [e.name for e in info.entities if info.body_alias[e.root_body]]


class RobotDescriptions:
    """
    The robot_description publishers of a node's entities.

    :param session: the loaded simulation; :meth:`on_model` is its listener.
    :param mesh_dir: where mesh geometry is written.
    """

    def __init__(self, node, session: Session, mesh_dir: Path):
        self._node = node
        self._session = session
        self._mesh_dir = mesh_dir
        self._pubs: dict = {}  # entity -> (publisher, the text last sent, its namespace)
        self._lock = threading.Lock()

    def on_model(self, loaded: Optional[Loaded], snap: Optional[Snapshot]) -> None:
        """Listen to the session's new models: describe its robots, drop those gone."""
        self.sync(None if snap is None else snap.info, loaded)

    def sync(self, info: Optional[ModelInfo], sim: Optional[Loaded]) -> None:
        """Describe a model generation's robots: new ones, and those whose text changed."""
        entities = [] if info is None or sim is None else described_entities(info)
        bases = {e.name: interface_base(e) for e in info.entities
                 if e.name in entities} if entities else {}
        with self._lock:
            for entity in [e for e, v in self._pubs.items() if bases.get(e) != v[2]]:
                self._node.destroy_publisher(self._pubs.pop(entity)[0])
        for entity in entities:
            try:
                text = sim.world.robot_description(entity, str(self._mesh_dir))
            except SimError:  # gone since this generation: the next sync drops it
                continue
            with self._lock:
                pub, sent, _ = self._pubs.get(entity, (None, None, None))
                if pub is None:
                    pub = self._node.create_publisher(
                        String, f'{bases[entity]}/robot_description', DESCRIPTION_QOS,
                        event_callbacks=PublisherEventCallbacks(use_default_callbacks=False))
                if text != sent:
                    pub.publish(String(data=text))
                self._pubs[entity] = (pub, text, bases[entity])

    def close(self) -> None:
        with self._lock:
            for pub, _, _ in self._pubs.values():
                self._node.destroy_publisher(pub)
            self._pubs.clear()
