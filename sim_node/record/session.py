"""
Recording a :class:`~sim_node.session.Session` with no ROS at all.

``/clock``, ``/tf`` and ``joint_states`` go into rosbag2 bags that ros2 bag play and Foxglove
open. The messages are built and serialized with ``rosbags``' own types (no rclpy, no ROS message
packages), from the session's snapshots at ``rate_hz`` of simulated time, on a thread of its
own; ``/tf`` carries every body's pose in the world frame (``world -> <body name>``). The node
records what it publishes instead (its ``record`` parameter), with its own frame tree::

    with Session() as session, SessionRecorder(session, 'runs/'):
        session.load_file('scenes/default.xml', WorldConfig(real_time_factor=0))
        session.step(5000)
"""

import threading
from typing import Optional

import numpy as np

from .bag import BagWriter, Limits
from ..session import Session


class SessionRecorder:
    """Records a session's snapshots (see the module docstring); close it, or use ``with``."""

    def __init__(self, session: Session, folder: str, rate_hz: float = 50.0,
                 limits: Limits = Limits(), world_frame: str = 'world'):
        from rosbags.typesys import get_typestore, Stores
        self._session, self._period = session, 1.0 / float(rate_hz)
        self._world = world_frame
        self._store = get_typestore(Stores.ROS2_JAZZY)
        self.writer = BagWriter(folder, limits)
        self._stop = threading.Event()
        self._last: Optional[float] = None
        self._loaded = session.loaded  # the newest world, recorded by the listener
        self._changed = threading.Event()
        session.add_listener(self._on_model)
        self._thread = threading.Thread(target=self._run, name='sim-session-recorder',
                                        daemon=True)
        self._thread.start()

    def _on_model(self, loaded, snap) -> None:
        """Note the world the session now has (a listener): the recorder's thread acts on it."""
        self._loaded = loaded
        self._changed.set()

    def close(self) -> None:
        self._session.remove_listener(self._on_model)
        self._stop.set()
        self._changed.set()
        self._thread.join(5)
        self.writer.close()

    def __enter__(self) -> 'SessionRecorder':
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _run(self) -> None:
        seq = -1
        loop = None
        while not self._stop.is_set():
            loaded = self._loaded
            if loaded is None or loaded.loop is None:  # nothing, or a world its owner steps
                self._changed.wait()
                self._changed.clear()
                continue
            if loaded.loop is not loop:  # another world: its snapshots count from its own
                loop, seq = loaded.loop, -1
            seq, snap = loop.wait_snapshot(seq, 0.1)
            if self._last is not None and 0 <= snap.time - self._last < self._period:
                continue
            self._last = snap.time
            self._record(snap)

    def _record(self, snap) -> None:
        t = self._store.types
        sec = int(snap.time)
        stamp = t['builtin_interfaces/msg/Time'](sec=sec, nanosec=int((snap.time - sec) * 1e9))
        ns = int(round(snap.time * 1e9))
        header = t['std_msgs/msg/Header']
        self._put('/clock', 'rosgraph_msgs/msg/Clock',
                  t['rosgraph_msgs/msg/Clock'](clock=stamp), ns)
        info = snap.info
        transforms = []
        for b in range(1, len(info.body_names)):
            p, q = snap.body_xpos[b], snap.body_xquat_wxyz[b]
            transforms.append(t['geometry_msgs/msg/TransformStamped'](
                header=header(stamp=stamp, frame_id=self._world),
                child_frame_id=info.body_names[b],
                transform=t['geometry_msgs/msg/Transform'](
                    translation=t['geometry_msgs/msg/Vector3'](x=p[0], y=p[1], z=p[2]),
                    rotation=t['geometry_msgs/msg/Quaternion'](x=q[1], y=q[2], z=q[3],
                                                               w=q[0]))))
        self._put('/tf', 'tf2_msgs/msg/TFMessage',
                  t['tf2_msgs/msg/TFMessage'](transforms=transforms), ns)
        if info.joint_names:
            self._put('/joint_states', 'sensor_msgs/msg/JointState', t[
                'sensor_msgs/msg/JointState'](
                    header=header(stamp=stamp, frame_id=''), name=list(info.joint_names),
                    position=np.asarray(snap.joint_position, dtype=np.float64),
                    velocity=np.asarray(snap.joint_velocity, dtype=np.float64),
                    effort=np.asarray(snap.joint_effort, dtype=np.float64)), ns)

    def _put(self, topic: str, msgtype: str, msg, ns: int) -> None:
        self.writer.put(topic, msgtype, self._store.serialize_cdr(msg, msgtype), ns)
