"""
What moves a live world's joints and bodies between steps, done under its lock.

:class:`Motion` is the control part of the :class:`~sim_node.core.world.World` facade: joint
trajectories started, checked and cancelled, mobile bases found (once per model) and driven,
pushes and PD gains. It works on the world's :class:`~sim_node.core.stepping.live.Live`
(duck-typed here: the control layer imports nothing of stepping) and its joint commands
(:class:`~.commands.Control`); each method takes the world lock for its whole change.
"""

from typing import Optional, Sequence

import numpy as np

from . import bases, drives, trajectory
from ..base.checks import check_finite
from ..base.errors import InvalidArgumentError


class Motion:
    """Trajectories, bases, pushes and gains of one live world (see the module docstring)."""

    def __init__(self, live):
        self.live = live
        self._bases: tuple = (-1, {})  # (generation, entity -> BaseSpec)

    def follow(self, entity: str, joint_names: Sequence[str], times, positions,
               velocities=(), accelerations=(), start_time: float = 0.0,
               path_tolerance: Optional[dict] = None, goal_tolerance: Optional[dict] = None,
               goal_time_tolerance: float = 0.0, allow_end_velocity: bool = False,
               open_loop: bool = False):
        """Start a trajectory (a new one preempts); return its run (see World)."""
        live = self.live
        with live.lock:
            start = ((lambda: live.control.commanded(entity, list(joint_names), live.index,
                                                     live.data)) if open_loop else None)
            traj = trajectory.plan(live.index, live.model, live.data, entity, joint_names,
                                   times, positions, velocities, accelerations, start_time,
                                   path_tolerance, goal_tolerance, goal_time_tolerance,
                                   allow_end_velocity, start)
            live.control.start_run(entity, trajectory.Tracker(traj), live.index, live.model,
                                   live.data)
            live.cached = None
            return live.control.run_of(entity)

    def check(self, entity: str, joint_names: Sequence[str], times, positions,
              velocities=(), accelerations=(), start_time: float = 0.0,
              allow_end_velocity: bool = False) -> None:
        """Raise what :meth:`follow` would refuse the goal for; start nothing."""
        live = self.live
        with live.lock:
            trajectory.plan(live.index, live.model, live.data, entity, joint_names, times,
                            positions, velocities, accelerations, start_time, None, None, 0.0,
                            allow_end_velocity)

    def cancel(self, entity: str, run) -> None:
        """End a trajectory run now; the joints hold where they are."""
        live = self.live
        with live.lock:
            live.control.cancel_run(entity, run, live.data, live.index, live.model)
            live.cached = None

    def bases(self) -> dict:
        """Return the entities with a mobile base: name -> :class:`~.bases.BaseSpec`."""
        with self.live.lock:
            return dict(self._bases_locked())

    def _bases_locked(self) -> dict:
        live = self.live
        if self._bases[0] != live.generation:
            live.kinematics_locked()
            self._bases = (live.generation, bases.find_all(
                live.model, live.data, live.index.entities, live.design.spawned))
        return self._bases[1]

    def drive(self, entity: str, vx: float, vy: float, wz: float, timeout: float) -> list:
        """Drive an entity's base (see World.drive); return what it could not take."""
        vx, vy, wz = drives.check_command(vx, vy, wz)
        live = self.live
        with live.lock:
            live.index.entity(entity)
            spec = self._bases_locked().get(entity)
            if spec is None:
                raise InvalidArgumentError(bases.ERR_NO_BASE.format(entity=entity))
            before = live.control.drive_of(entity)
            notes = []
            if vy and spec.kind == bases.DIFF_DRIVE:
                notes.append(drives.NOTE_SIDEWAYS.format(entity=entity, vy=vy))
            if before is not None and before.saturated:
                notes.append(drives.NOTE_BEYOND.format(entity=entity))
            if live.control.command_base(spec, vx, vy, wz, max(0.0, float(timeout)),
                                         live.index, live.model, live.data):
                live.cached = None  # the controls changed: the last batch's state is stale
        return notes

    def push(self, body: str, force: Sequence[float], torque: Sequence[float]) -> None:
        """Hold a force and torque on a body from the next step (see World.push)."""
        wrench = np.concatenate([check_finite('force', force, 3),
                                 check_finite('torque', torque, 3)])
        live = self.live
        with live.lock:
            live.data.xfrc_applied[live.index.body(body)] = wrench

    def set_gains(self, kp: float, kd: float) -> None:
        live = self.live
        with live.lock:
            live.control.set_gains(kp, kd, live.index, live.model, live.data)
            live.cached = None
