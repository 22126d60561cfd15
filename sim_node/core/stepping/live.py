"""
The world as it runs now: the world lock and everything it guards, in one object.

A :class:`Live` holds the current model, data and index, the edit phase's
:class:`~sim_node.core.stepping.design.Design` and the generation, the step count, the joint
commands (:class:`~sim_node.core.control.commands.Control`), the divergence guard, and what is
derived from the state and may be stale (body poses after a step, the clean state the last
batch left). The facade (:class:`~sim_node.core.world.World`), the stepping protocol
(:mod:`.steps`), the edit transaction (:mod:`sim_node.core.editing.transaction`) and the state
writes (:mod:`sim_node.core.editing.writes`) all work on one ``Live``: its attributes are public
so that they can, and every method whose name ends in ``_locked`` expects the caller to hold
:attr:`lock` (``with live.lock:``).
"""

import threading
from typing import Optional

import mujoco
import numpy as np

from . import sampling
from .design import Design
from .guard import DivergenceGuard
from .lock import WorldLock
from ..base.config import WorldConfig
from ..base.errors import InvalidPoseError
from ..base.records import Clock, Snapshot
from ..compiled import index as model_index
from ..compiled import state
from ..compiled.index import ModelIndex, STATE_SPEC
from ..control.commands import Control

ERR_FRAME = ('the pose is given in frame {frame!r}, which is not known: use the world frame '
             "('' or 'world') or the name of an entity")


class Live:
    """
    The run phase's state, guarded by :attr:`lock` (reentrant; see ``sim_node.core``).

    :param design: the edit phase's state the first model was compiled from.
    :param model: that model; a fresh MjData is made for it and reset to the initial state.
    """

    def __init__(self, config: WorldConfig, design: Design, model: mujoco.MjModel):
        self.config = config
        self.lock = WorldLock()
        self.control = Control(config.kp, config.kd)
        self.guard = DivergenceGuard()
        self.design = design
        self.generation = 0
        self.step_count = 0
        self.resets = 0  # resets of state: a sample taken before one is stale after it
        self.snapshot_seq = 0
        #: The clock the loop's last batch left, while nothing changed since (see stepping).
        self.batch_clock: Optional[Clock] = None
        #: The state after the last clean batch while nothing has changed it since, else None:
        #: every write of the state clears it (the next step then reads the state anew).
        self.cached: Optional[np.ndarray] = None
        #: The state after the last clean batch, whatever happened since (divergence fallback).
        self.last_good: Optional[np.ndarray] = None
        #: Body poses (and velocities) describe the state one step back (see kinematics_locked).
        self.stale_kinematics = self.stale_dynamics = True
        #: Notified (a leaf lock) each time a new model becomes the world's.
        self.new_model = threading.Condition(threading.Lock())
        #: Called (no argument, under the world lock: they must not block) after each new
        #: model: an owner's wake-up (:meth:`World.add_model_watcher`).
        self.model_watchers: list = []
        #: Declared sensors sampled as the world steps (:mod:`.sampling`), and their queue.
        self.sampler = None
        self.samples = sampling.new_queue()
        #: The entities whose contacts are reported (:meth:`World.report_contacts`).
        self.contact_request = sampling.request(config.contact_entities,
                                                config.contact_rate_hz)
        #: Joints sampled at a rate ((key, names, Hz, sensors, tick),
        #: :meth:`World.sample_joints`): replaced whole under :attr:`requests_lock` (a leaf),
        #: without the world lock; the stepping side reads it once per batch.
        self.joint_requests: tuple = ()
        #: Lasers whose poses are taken at their rates ((site, Hz), :meth:`World.scan_lasers`),
        #: replaced the same way, and the queue of those poses.
        self.laser_requests: tuple = ()
        self.laser_poses = sampling.new_laser_queue()
        self.requests_lock = threading.Lock()
        self.adopt_locked(model, mujoco.MjData(model))
        #: The model and its index, replaced together in one assignment once a new model is
        #: the world's (never while a switch may still go back): read without the world lock
        #: by :meth:`World.model_info <sim_node.core.world.World.model_info>` and
        #: :meth:`World.live_model <sim_node.core.world.World.live_model>`, a pair that is
        #: always of one generation.
        self.current: tuple = (self.model, self.index)
        self.reset_state_locked(keep_time=False)

    def holds_lock(self) -> bool:
        """Whether the calling thread holds the world lock."""
        return self.lock.lock._is_owned()

    # ---------------------------------------------------------------- reads

    def clock_locked(self) -> Clock:
        return Clock(float(self.data.time), self.step_count, float(self.model.opt.timestep),
                     self.resets)

    def snapshot_locked(self) -> Snapshot:
        """Return an immutable copy for publishers, numbered (``seq``)."""
        if self.stale_kinematics:
            # Body poses only: a third of kinematics_locked's cost (1,000 bodies at 200 Hz),
            # which stays due for readers of velocities.
            mujoco.mj_kinematics(self.model, self.data)
        self.snapshot_seq += 1
        return state.snapshot(self.data, self.index, self.step_count, self.snapshot_seq)

    def kinematics_locked(self) -> None:
        """
        Bring body poses and velocities up to the current state before reading them.

        mj_step computes them before integrating, so afterwards they describe the state one
        step earlier than qpos, qvel and time (MuJoCo's convention, kept for the Gym
        environment's observations as in Gymnasium). Recomputing them changes no state.
        """
        if self.stale_kinematics:
            m, d = self.model, self.data
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            mujoco.mj_comVel(m, d)
            self.stale_kinematics = False

    def dynamics_locked(self) -> None:
        """
        Bring accelerations up to date too, as :meth:`kinematics_locked` does poses.

        mj_forward, then the body accelerations mj_objectAcceleration reads. Changes no state
        either.
        """
        m, d = self.model, self.data
        if self.stale_dynamics:
            mujoco.mj_forward(m, d)
            self.stale_kinematics = self.stale_dynamics = False
        mujoco.mj_rnePostConstraint(m, d)

    def frame_locked(self, name: str) -> tuple:
        """Return (position (3,), quat_wxyz (4,)) of an entity's root body, now."""
        rec = self.index.entity(name)
        self.kinematics_locked()
        return state.body_pose(self.data, rec.root_body)

    def pose_frame_locked(self, name: str) -> tuple:
        """Return the pose of the frame a written pose is given in; unknown: an invalid pose."""
        if name not in self.index.entity_by_name:
            raise InvalidPoseError(ERR_FRAME.format(frame=name[:200]))
        return self.frame_locked(name)

    # ---------------------------------------------------------------- writes

    def changed_locked(self) -> None:
        """Say that something besides the loop changed the state (readers recompute)."""
        self.cached = None
        self.stale_kinematics = self.stale_dynamics = True

    def forward_locked(self) -> None:
        """After writing state: derived quantities now, warnings taken as seen."""
        self.cached = None
        mujoco.mj_forward(self.model, self.data)
        self.stale_kinematics = self.stale_dynamics = False
        self.guard.note()

    def set_state_locked(self, values: np.ndarray, step: int) -> None:
        """Write a full integration state (layout: :data:`.compiled.index.STATE_SPEC`)."""
        mujoco.mj_setState(self.model, self.data, values, STATE_SPEC)
        self.step_count = step
        self.forward_locked()

    def reset_state_locked(self, keep_time: bool) -> None:
        """Back to the `home` keyframe (or the initial state); held commands are dropped."""
        m, d = self.model, self.data
        t, steps = d.time, self.step_count
        self.resets += 1
        self.control.clear(self.index, m, d)
        key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, 'home')
        if key >= 0:
            mujoco.mj_resetDataKeyframe(m, d, key)
        else:
            mujoco.mj_resetData(m, d)
        if keep_time:
            d.time, self.step_count = t, steps
        else:
            self.step_count = 0
        self.forward_locked()

    def adopt_locked(self, model: mujoco.MjModel, data: mujoco.MjData,
                     index: Optional[ModelIndex] = None) -> None:
        """
        Switch everything to a new model and data together (index, control, guard).

        :param index: the model's index if it was built beforehand (outside the lock) for
            this generation and spawned table.
        """
        self.model, self.data = model, data
        if index is None or index.generation != self.generation:
            index = model_index.build(model, self.generation, self.design.spawned)
        self.index: ModelIndex = index
        self.ctrl = data.ctrl
        self.good_buf = np.empty(self.index.state_size)
        self.copy_state = state.state_copier(model, data, STATE_SPEC)
        self.last_good = None  # its layout belongs to the old model
        self.control.bind(self.index, model, data, new_model=True)
        # Derived quantities (xpos, contacts) are zero until mj_forward runs.
        self.guard.bind(data)
        self.forward_locked()

    def switch_locked(self, design: Design, model: mujoco.MjModel, data: mujoco.MjData,
                      index: Optional[ModelIndex] = None) -> None:
        """Make a new design, model and data the world's, raising the generation; or nothing."""
        saved = (self.design, self.generation, self.model, self.data, self.control.held_copy())
        try:
            self.design = design
            self.generation += 1
            self.adopt_locked(model, data, index)
        except BaseException:
            # Whatever failed while switching over (index, commands, guard), the world goes
            # back to exactly what it was: a request that fails changes nothing.
            self.design, self.generation, model, data, held = saved
            self.control.restore_held(held)
            self.adopt_locked(model, data)
            raise
        self.current = (self.model, self.index)
        with self.new_model:
            self.new_model.notify_all()
        for watcher in list(self.model_watchers):
            watcher()

    def wait_new_model(self, after: int, timeout: float) -> int:
        """Block until the generation is no longer `after` (or `timeout` s); return it."""
        with self.new_model:
            self.new_model.wait_for(lambda: self.generation != after, timeout)
        return self.generation
