"""
/tf of successive snapshots, never a frame twice with one stamp (pure: no rclpy).

Every tf2 listener (RViz too) drops a transform whose stamp it already has and logs
TF_REPEATED_DATA. So when time has not moved since the last /tf (paused, stalled, a service's
snapshot), only frames not yet sent at this stamp go out: those of an entity spawned meanwhile.
A pose set while paused shows on /tf with the next step. A reset (time going back) sends
everything again: listeners handle that by the time jump.
"""

from typing import Optional

import numpy as np
from sim_node.core.base.records import ModelInfo, Snapshot

from . import convert


class TfStream:
    """
    Turns the snapshots of one loop into /tf messages (serialized), one per new snapshot.

    :param world_frame: the frame of the world body, without the prefix.
    :param frame_prefix: prepended to every frame id.
    """

    def __init__(self, world_frame: str, frame_prefix: str = ''):
        self.world_frame = world_frame
        self.prefix = frame_prefix
        self._elsewhere: frozenset = frozenset()
        self._start(None)

    def set_elsewhere(self, entities: frozenset) -> None:
        """
        Leave out the world transform of these entities' root bodies (from the next message).

        Another publisher sends it (a mobile base's world -> odom -> base): a frame with two
        parents would break every tf2 listener.
        """
        if entities != self._elsewhere:
            self._elsewhere = frozenset(entities)
            self._generation = None  # plan again

    def _start(self, source: object) -> None:
        self._source = source  # the loop the snapshots come from: a new one starts over
        self._generation: Optional[int] = None
        self._seq = -1
        self._frames: tuple = ()  # TF frame of each body of the planned generation
        self._moving = np.zeros(0, dtype=int)
        self._chains: tuple = ()  # moving intermediate links of descriptions
        self._template = None
        self._time: Optional[float] = None  # the stamp of the last /tf
        self._layout: tuple = ((), None)  # (frame names, moving bodies) that /tf went with
        self._added: set = set()  # frames sent since at the same stamp (new entities)

    def message(self, source: object, seq: int, snap: Snapshot) -> Optional[bytes]:
        """
        Return the /tf message of snapshot number `seq` of `source`, or None (nothing new).

        :param source: what numbers the snapshots (the loop): another one starts over.
        """
        if source is not self._source:
            self._start(source)
        info = snap.info
        if info.generation != self._generation:
            self._plan(info)
        if seq == self._seq:
            return None
        self._seq = seq
        if not len(self._moving):
            return None
        if snap.time != self._time:
            self._time = snap.time
            self._layout, self._added = (self._frames, self._moving), set()
            return convert.moving_tf(self._template, info, snap, self._moving, self._chains)
        frames, moving = self._layout
        if moving is self._moving:  # the layout it went with: every frame went already
            return None
        sent = {frames[b] for b in moving} | self._added  # built only when time stands
        new = np.array([b for b in self._moving if self._frames[b] not in sent], dtype=int)
        if not len(new):
            return None
        self._added |= {self._frames[b] for b in new}
        chains = tuple(c for c in self._chains if c.body in set(new.tolist()))
        template = convert.moving_tf_template(info, new, self._frames, self.prefix, chains)
        return convert.moving_tf(template, info, snap, new, chains)

    def _plan(self, info: ModelInfo) -> None:
        """Plan /tf of a new model generation: its moving bodies, their frames, the template."""
        self._generation = info.generation
        moving = convert.moving_body_ids(info)
        names = info.body_names
        self._moving = np.array([b for b in moving if not (info.body_root[b] == b and names[b]
                                                           in self._elsewhere)], dtype=int)
        self._frames = convert.frame_names(info, self.world_frame, self.prefix)
        self._chains = tuple(c for c in info.chains if not c.static)
        self._template = convert.moving_tf_template(info, self._moving, self._frames,
                                                    self.prefix, self._chains)
