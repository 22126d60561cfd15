"""
Writing the state of a world: entity poses and twists, joint positions and velocities.

Each method of :class:`Writes` locks the world (its :class:`~sim_node.core.stepping.live.Live`),
checks everything, then writes (see :mod:`sim_node.core.compiled.state`): an error changes nothing.
:class:`~sim_node.core.world.World` delegates to it.
"""

from typing import Optional, Sequence

import numpy as np

from . import editor
from .transaction import Transaction
from ..base import checks, quat
from ..base.checks import check_finite, check_pose
from ..base.errors import IncorrectStateError, InvalidArgumentError, OperationFailedError
from ..base.records import EntityRecord, PhysicsState
from ..compiled import state
from ..stepping.design import Edit
from ..stepping.guard import clean
from ..stepping.live import Live

ERR_STATIC_ACCELERATION = ('{name!r} is a {category} entity welded to the world: it cannot '
                           'have an acceleration (only its pose can be set)')
ERR_STATIC_TWIST = ('{name!r} is a {category} entity welded to the world: it cannot have a '
                    'velocity (only its pose can be set)')


ERR_STATE_GENERATION = ('this state was taken from model generation {got}, the world is now at '
                        'generation {now} (an entity was spawned or deleted since)')


class Writes:
    """State overwrite of a :class:`~sim_node.core.stepping.live.Live` world."""

    def __init__(self, live: Live, transaction: Transaction):
        self.live = live
        self.transaction = transaction

    def set_state(self, physics_state: PhysicsState) -> None:
        """Overwrite the full state with one taken from the same model generation."""
        live = self.live
        with live.lock:
            if physics_state.generation != live.index.generation:
                raise IncorrectStateError(ERR_STATE_GENERATION.format(
                    got=physics_state.generation, now=live.index.generation))
            values = np.asarray(physics_state.values, dtype=float)
            if values.shape != (live.index.state_size,) or not clean(values):
                raise InvalidArgumentError(checks.ERR_NOT_FINITE.format(
                    what='state values', value=f'{values.size} values'))
            live.set_state_locked(values, physics_state.step)

    def set_entity_state(self, name: str, position: Optional[Sequence[float]] = None,
                         quat_wxyz: Optional[Sequence[float]] = None,
                         linear_velocity: Optional[Sequence[float]] = None,
                         angular_velocity: Optional[Sequence[float]] = None,
                         reference: str = '',
                         acceleration: Optional[Sequence[float]] = None) -> None:
        """
        Set the pose and/or twist of an entity's root body (world frame or `reference`).

        A free body is moved through its free joint. A welded entity (static object or
        fixed-base robot) can be moved (its model is rebuilt, keeping all state) but its
        twist, and its `acceleration` (linear then angular, 6 values), must be zero. An
        acceleration is otherwise not applied (MuJoCo computes its own; the standard allows
        ignoring it).
        """
        acc = None if acceleration is None else check_finite('acceleration', acceleration, 6)
        with self.live.lock:
            rec = self.live.index.entity(name)
            if acc is not None and np.any(acc != 0) and not rec.has_free_joint:
                raise OperationFailedError(ERR_STATIC_ACCELERATION.format(
                    name=rec.name, category=rec.category))
            self._overwrite_locked({name: (position, quat_wxyz)},
                                   {name: (linear_velocity, angular_velocity)}, {}, {},
                                   reference)

    def overwrite(self, poses: Optional[dict] = None, twists: Optional[dict] = None,
                  joint_positions: Optional[dict] = None,
                  joint_velocities: Optional[dict] = None) -> None:
        """
        Overwrite any parts of the state at once, in the world frame.

        ``poses`` {entity: (position, quat_wxyz)}, ``twists`` {entity: (linear, angular)}, and
        {joint: value} for hinge/slide joint positions and velocities.

        Everything is checked before anything changes, so an error changes nothing. An
        entity without a free joint given its current pose stays put (no rebuild); given
        another pose it is moved (model rebuilt, state kept), and a non-zero twist for it is
        refused.
        """
        with self.live.lock:
            self._overwrite_locked(poses or {}, twists or {}, joint_positions or {},
                                   joint_velocities or {}, '')

    def _overwrite_locked(self, poses: dict, twists: dict, joint_positions: dict,
                          joint_velocities: dict, reference: str) -> None:
        idx, d = self.live.index, self.live.data
        self.live.kinematics_locked()
        frame = self.live.pose_frame_locked(reference) if reference else None
        targets = {}  # entity -> (record, pos, quat, lin, ang), checked, in the world frame
        for n in (*poses, *twists):
            rec = idx.entity(n)
            targets[n] = (rec, *self._check_target_locked(
                rec, *poses.get(n, (None, None)), *twists.get(n, (None, None)), frame))
        q_adr, q_values = self._joint_targets_locked('position', joint_positions, True)
        v_adr, v_values = self._joint_targets_locked('velocity', joint_velocities, False)
        welded_moves = []
        for rec, pos, q, lin, ang in targets.values():
            if rec.has_free_joint:
                continue
            if any(v is not None and np.any(v != 0) for v in (lin, ang)):
                raise OperationFailedError(ERR_STATIC_TWIST.format(name=rec.name,
                                                                   category=rec.category))
            root = rec.root_body
            if pos is not None and not (
                    np.allclose(pos, d.xpos[root], rtol=0, atol=1e-9)
                    and abs(abs(float(np.dot(q, d.xquat[root]))) - 1.0) < 1e-12):
                welded_moves.append((rec, pos, q))
        if welded_moves:  # all moves in one rebuild, before the direct writes
            m = self.live.model
            self.transaction.edit_locked(Edit(lambda spec: [editor.move_group(
                spec, self.live.design.frame_of(rec.name), rec.name,
                (m.body_pos[rec.root_body], m.body_quat[rec.root_body]), pos, q)
                for rec, pos, q in welded_moves]))
        for rec, pos, q, lin, ang in targets.values():
            if rec.has_free_joint:
                state.write_free_body(self.live.model, self.live.data, rec, pos, q, lin, ang)
        self.live.data.qpos[q_adr] = q_values
        self.live.data.qvel[v_adr] = v_values
        self.live.forward_locked()

    def _check_target_locked(self, rec: EntityRecord, position, quat_wxyz, linear, angular,
                             frame: Optional[tuple]) -> tuple:
        """
        Check world-frame (pos, quat, lin, ang), None where not given.

        A pose given by one half keeps the current other half.
        """
        pos = q = lin = ang = None
        if position is not None or quat_wxyz is not None:
            cur_pos, cur_q = state.body_pose(self.live.data, rec.root_body)
            if frame is not None:
                cur_pos, cur_q = quat.to_frame(*frame, cur_pos, cur_q)
            pos, q = check_pose(cur_pos if position is None else position,
                                cur_q if quat_wxyz is None else quat_wxyz)
            if frame is not None:
                pos, q = quat.from_frame(*frame, pos, q)
            checks.check_extent(pos, self.live.config.world_extent)
        if linear is not None:
            lin = check_finite('linear velocity', linear, 3)
        if angular is not None:
            ang = check_finite('angular velocity', angular, 3)
        if frame is not None:
            lin = None if lin is None else quat.rotate(frame[1], lin)
            ang = None if ang is None else quat.rotate(frame[1], ang)
        return pos, q, lin, ang

    def _joint_targets_locked(self, what: str, values: dict, use_qpos: bool) -> tuple:
        """Check (qpos or qvel addresses, values) for {joint: value}."""
        i = self.live.index.joints(values.keys())
        vals = check_finite(f'joint {what}s', list(values.values()))
        index = self.live.index
        return (index.joint_qposadr if use_qpos else index.joint_dofadr)[i], vals
