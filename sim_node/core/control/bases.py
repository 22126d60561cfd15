"""
Mobile bases: velocity commands for differential-drive and holonomic planar robots, odometry.

An entity has a base when (first match wins):

* its URDF carries a Gazebo drive plugin: diff drive (``libgazebo_ros_diff_drive.so``, ROS 1's
  ``<leftJoint>`` spelling too, or ``gz-sim-diff-drive-system`` with one or more joints a side)
  or planar move (``libgazebo_ros_planar_move.so``, for a floating root);
* it has hinge joints named as wheels, ``left`` and ``right`` (``left_wheel_joint``,
  ``wheel_right``...): differential drive;
* two slide joints with horizontal axes and a hinge with a vertical one (robosuite's mobile
  bases): holonomic planar.

Wheel radius and separation are measured from the model (a plugin's values win where it gives
them): the radius from the wheel's colliding geoms across its axis, the separation between the
left and right anchors along it, the sign of each wheel from which way its axis turns it
forward. A command ``(vx, vy, wz)`` in the base's frame becomes wheel speeds (``v -+ wz s / 2``
over ``r``), joint velocities of the planar joints, or the floating root's velocity (planar
move, as Gazebo's plugin sets it). Wheels and planar joints go through their velocity actuators
(``ctrl = gear * speed``, within ``ctrlrange``) where they have one (a spawned wheeled model
is given them, :mod:`.wheels`), else a velocity loop ``M (kd (w* - w)) + bias`` through their
motor (within its limits) or ``qfrc_applied``. The command itself is a target for the base's
own motion: a tracking loop (:meth:`Drive._track`, every :data:`TRACK_PERIOD` of simulated
time) adds what casters, slip and friction loss take, within :data:`TRACK_LIMIT` times the
command. Wheel speed and acceleration are limited; no command for :data:`COMMAND_TIMEOUT`
simulated seconds stops the base, as diff_drive_controller does, on time even inside a batch
of steps. It is physics: the base pushes, slips and stops at walls.

:class:`.odometry.BaseOdometry` integrates a base's pose from its wheel angles (it drifts with
slip, as a real robot's does) or takes the simulation's ground truth; ROS-free, used by the
node's ``<entity>/odom``. What a spawn adds to a wheeled model (wheel actuators, rolling
casters) is :mod:`.wheels`.
"""

from dataclasses import dataclass
import math
from typing import Optional, Sequence

import mujoco
import numpy as np

from .odometry import BaseOdometry as Odometry  # noqa: F401 (the name older code imports)
from ..base import quat

DIFF_DRIVE, PLANAR_JOINTS, PLANAR_FREE = 'diff_drive', 'planar_joints', 'planar_free'
#: Seconds of simulated time without a command after which a base stops.
COMMAND_TIMEOUT = 0.5
#: What a drive needs after a step (see :meth:`Drive.apply`).
EVERY_STEP, EVERY_BATCH = 'step', 'batch'
#: The tracking loop (:meth:`Drive._track`): integral gain (1/s), the most it adds (times the
#: command, axis by axis: an axis commanded 0 gets nothing), the longest interval it
#: integrates at once (s).
TRACK_GAIN, TRACK_LIMIT, TRACK_DT_MAX = 8.0, 10.0, 0.05
#: Simulated seconds between two runs of a base's tracking loop (20 Hz: it only trims what the
#: velocity actuators hold, every step, in MuJoCo).
TRACK_PERIOD = 0.05
#: The largest command taken (m/s, rad/s): beyond is no base's, and would blow the physics up.
MAX_SPEED, MAX_TURN = 50.0, 50.0
ERR_NO_BASE = ('entity {entity!r} has no mobile base: no wheel joints named left and right, no '
               'planar joints and no Gazebo drive plugin in its URDF')
NOTE_SIDEWAYS = ('{entity!r} is a differential drive: it cannot move sideways, so vy={vy:g} '
                 'is ignored')
NOTE_BEYOND = ('{entity!r} cannot move as commanded: it needs more than its actuators give '
               '(their control range, or more than the tracking loop adds); it moves as far '
               'as they take it')
ERR_COMMAND = ('a base command must be finite, |linear| <= {speed:g} m/s and |angular| <= '
               '{turn:g} rad/s; got vx={vx}, vy={vy}, wz={wz}')
_HINGE, _SLIDE, _FREE = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE),
                         int(mujoco.mjtJoint.mjJNT_FREE))
_DIFF_PLUGINS = ('diff_drive', 'diff-drive', 'diffdrive')
_PLANAR_PLUGINS = ('planar_move',)


@dataclass(frozen=True)
class BaseSpec:
    """
    What drives an entity's base, as found in its model (see the module docstring).

    Joint names are as on joint_states (``<entity>/<joint>``). ``signs``: per wheel, +1 when
    turning it positively drives the base forward. Limits are +-inf when not given.
    """

    entity: str
    kind: str
    found_by: str  # 'gazebo plugin', 'wheel names', 'planar joints'
    left: tuple = ()
    right: tuple = ()
    signs: tuple = ()  # for left + right, in that order
    radius: float = 0.0
    separation: float = 0.0
    planar: tuple = ()  # (slide, slide, hinge) joint names of a holonomic planar base
    max_wheel_speed: float = math.inf  # rad/s
    max_wheel_acceleration: float = math.inf  # rad/s^2
    max_wheel_torque: float = math.inf  # N m
    odom_frame: str = 'odom'
    base_frame: str = ''  # the plugin's robot base frame ('' : the description's root link)

    @property
    def wheels(self) -> tuple:
        return self.left + self.right


def drive_plugin(extensions: Sequence) -> Optional[dict]:
    """
    Read a Gazebo drive plugin out of a URDF's extension elements.

    The elements are those :class:`sim_node.core.models.urdf.Prepared` kept.

    :returns: {'kind', 'left', 'right', 'separation', 'radius', 'max_acceleration',
        'max_torque', 'odom_frame', 'base_frame'} (values absent: missing), or None.
    """
    for ext in extensions:
        for plugin in ext.iter('plugin'):
            name = (plugin.get('filename', '') + ' ' + plugin.get('name', '')).lower()

            def text(*tags):
                for tag in tags:
                    found = [e.text.strip() for e in plugin.iter(tag) if e.text and e.text.strip()]
                    if found:
                        return found
                return []

            def number(*tags):
                values = text(*tags)
                try:
                    return float(values[0]) if values else None
                except ValueError:
                    return None
            frames = {'odom_frame': (text('odometry_frame', 'odometryFrame', 'frame_id') or
                                     ['odom'])[0],
                      'base_frame': (text('robot_base_frame', 'robotBaseFrame', 'child_frame_id')
                                     or [''])[0]}
            if any(k in name for k in _DIFF_PLUGINS):
                diameter = number('wheel_diameter', 'wheelDiameter')
                return {'kind': DIFF_DRIVE, 'left': text('left_joint', 'leftJoint'),
                        'right': text('right_joint', 'rightJoint'),
                        'separation': number('wheel_separation', 'wheelSeparation'),
                        'radius': (number('wheel_radius') if diameter is None
                                   else diameter / 2),
                        'max_acceleration': number('max_wheel_acceleration',
                                                   'wheelAcceleration'),
                        # Gazebo's plugin limits the wheels to 20 N m unless told
                        'max_torque': number('max_wheel_torque', 'wheelTorque') or 20.0,
                        **frames}
            if any(k in name for k in _PLANAR_PLUGINS):
                return {'kind': PLANAR_FREE, **frames}
    return None


def find_all(model, data, entities, spawned: dict) -> dict:
    """Return entity name -> :class:`BaseSpec` for every entity with a mobile base."""
    found = {}
    for rec in entities:
        spec = find(model, data, rec.name, rec.body_ids,
                    getattr(spawned.get(rec.name), 'drive', None))
        if spec is not None:
            found[rec.name] = spec
    return found


def find(m: mujoco.MjModel, d: mujoco.MjData, entity: str, bodies: Sequence[int],
         plugin: Optional[dict] = None) -> Optional[BaseSpec]:
    """
    Return the base of one entity (its bodies, root first), or None.

    `d` must have its kinematics computed (anchors and axes are measured from it).
    """
    prefix = entity + '/'
    joints = [j for b in bodies for j in range(m.body_jntadr[b], m.body_jntadr[b]
                                               + m.body_jntnum[b])]

    def jname(j: int) -> str:  # as on joint_states
        return mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) or f'joint_{j}'

    def own(j: int) -> str:  # as in the entity's own file
        name = jname(j)
        return name[len(prefix):] if name.startswith(prefix) else name

    frames = {k: plugin[k] for k in ('odom_frame', 'base_frame')} if plugin else {}
    if plugin and plugin['kind'] == PLANAR_FREE:
        root = bodies[0]
        if m.body_jntnum[root] and int(m.jnt_type[m.body_jntadr[root]]) == _FREE:
            return BaseSpec(entity, PLANAR_FREE, 'gazebo plugin', **frames)
    by_name = {own(j): j for j in joints if int(m.jnt_type[j]) == _HINGE}
    if plugin and plugin['kind'] == DIFF_DRIVE:
        left = [by_name[n] for n in plugin['left'] if n in by_name]
        right = [by_name[n] for n in plugin['right'] if n in by_name]
        if left and right:
            return _diff(m, d, entity, left, right, 'gazebo plugin', plugin, jname, frames)
    wheels = [j for n, j in by_name.items() if 'wheel' in n.lower()]
    left = [j for j in wheels if 'left' in own(j).lower()]
    right = [j for j in wheels if 'right' in own(j).lower()]
    if left and right:
        return _diff(m, d, entity, left, right, 'wheel names', {}, jname, frames)
    planar = _planar_joints(m, joints)
    if planar is not None:
        return BaseSpec(entity, PLANAR_JOINTS, 'planar joints',
                        planar=tuple(jname(j) for j in planar), **frames)
    return None


def _diff(m, d, entity: str, left: list, right: list, found_by: str, plugin: dict, jname,
          frames: dict) -> Optional[BaseSpec]:
    root = int(m.body_rootid[m.jnt_bodyid[left[0]]])
    base = int(m.body_parentid[m.jnt_bodyid[left[0]]])
    forward = d.xmat[base].reshape(3, 3)[:, 0]
    up = np.array([0.0, 0.0, 1.0])
    signs, radii = [], []
    for j in left + right:
        axis = d.xaxis[j]
        signs.append(1.0 if float(np.dot(np.cross(axis, up), forward)) >= 0 else -1.0)
        radii.append(_wheel_radius(m, int(m.jnt_bodyid[j]), m.jnt_axis[j]))
    axis = d.xaxis[left[0]]
    lc = np.mean([d.xanchor[j] for j in left], axis=0)
    rc = np.mean([d.xanchor[j] for j in right], axis=0)
    separation = plugin.get('separation') or abs(float(np.dot(lc - rc, axis)))
    radius = plugin.get('radius') or float(np.median(radii))
    if not (separation > 0 and radius > 0) or root == 0:
        return None
    return BaseSpec(
        entity, DIFF_DRIVE, found_by, tuple(jname(j) for j in left),
        tuple(jname(j) for j in right), tuple(signs), float(radius), float(separation),
        max_wheel_acceleration=plugin.get('max_acceleration') or math.inf,
        max_wheel_torque=plugin.get('max_torque') or math.inf, **frames)


def _wheel_radius(m: mujoco.MjModel, body: int, axis: np.ndarray) -> float:
    """Return a wheel's radius across its axis, from its colliding geoms (else any), or 0."""
    geoms = range(m.body_geomadr[body], m.body_geomadr[body] + m.body_geomnum[body])
    solid = [g for g in geoms if m.geom_contype[g] or m.geom_conaffinity[g]] or list(geoms)
    best = 0.0
    for g in solid:
        local = quat.rotate(quat.conj(m.geom_quat[g]), axis)  # the axis in the geom's frame
        half = m.geom_aabb[g, 3:]
        across = [half[k] for k in range(3) if abs(local[k]) < 0.5]
        if across:
            best = max(best, float(max(across)))
    return best


def _planar_joints(m: mujoco.MjModel, joints: list) -> Optional[tuple]:
    """Two slides with horizontal axes and a vertical hinge: (slide, slide, hinge)."""
    slides = [j for j in joints if int(m.jnt_type[j]) == _SLIDE and abs(m.jnt_axis[j][2]) < 0.1]
    hinges = [j for j in joints if int(m.jnt_type[j]) == _HINGE and abs(m.jnt_axis[j][2]) > 0.9]
    if len(slides) < 2 or not hinges:
        return None
    a, b = m.jnt_axis[slides[0]][:2], m.jnt_axis[slides[1]][:2]
    if abs(a[0] * b[1] - a[1] * b[0]) < 0.5:  # parallel: not a plane
        return None
    return slides[0], slides[1], hinges[0]


class Drive:
    """
    One base's controller, bound to one model's addresses (world lock held, before each step).

    :param kd: the velocity loop's gain per unit of joint inertia (1/s), for joints without a
        velocity actuator.
    """

    def __init__(self, spec: BaseSpec):
        self.spec = spec
        self.command = Command()
        self.speeds = np.zeros(len(spec.wheels) if spec.kind == DIFF_DRIVE else 3)
        self.integral: Optional[np.ndarray] = None  # the velocity loops' integral terms
        self.changed = True  # the last apply wrote controls other than those in force
        self._index = None
        #: The tracking loop's correction of the command (vx, vy, wz) (see :meth:`_track`).
        self.trim = [0.0, 0.0, 0.0]
        self._vel = np.zeros(6)
        #: Whether the last command needed more than the model's actuators give.
        self.saturated = False
        self._seen: Optional[float] = None
        self._fresh = False  # whether its command was in force at the last apply

    def due(self, now: float) -> bool:
        """
        Whether it needs an :meth:`apply` between batches at simulated time `now`.

        Its velocity actuators hold the speeds meanwhile: it is due when its command times
        out, and every :data:`TRACK_PERIOD` for the tracking loop (a controller's update rate),
        not before every batch (two bases cost the loop 17% of its speed that way).
        """
        cmd = self.command
        fresh = cmd.timeout <= 0 or now - cmd.time <= cmd.timeout
        return fresh != self._fresh or (fresh and (
            self._seen is None or now - self._seen >= TRACK_PERIOD))

    def bind(self, index, model: mujoco.MjModel) -> bool:
        """Take the addresses of its joints in `index`; False if one is gone."""
        from .actuation import Outputs
        from ..base.records import VELOCITY
        names = self.spec.wheels if self.spec.kind == DIFF_DRIVE else self.spec.planar
        if self.spec.kind == PLANAR_FREE:
            root = index.entity_by_name.get(self.spec.entity)
            if root is None or not model.body_jntnum[root.root_body]:
                return False
            j = model.body_jntadr[root.root_body]
            if int(model.jnt_type[j]) != _FREE:
                return False
            self.free_dof = int(model.jnt_dofadr[j])
            self._index = index
            return True
        if any(n not in index.joint_index for n in names):
            return False
        idx = np.array([index.joint_index[n] for n in names], dtype=int)
        self.dof = index.joint_dofadr[idx]
        self.jids = index.joint_ids[idx]
        # the body whose motion is the base's: the wheels' parent, the planar hinge's body
        self.body = int(model.body_parentid[model.jnt_bodyid[self.jids[0]]]
                        if self.spec.kind == DIFF_DRIVE else model.jnt_bodyid[self.jids[2]])
        acts = np.array([index.joint_actuators[i].get(VELOCITY, -1) for i in idx], dtype=int)
        self.act = acts
        a = np.maximum(acts, 0)
        self.gear = np.where(acts >= 0, model.actuator_gear[a, 0] if model.nu else 1.0, 1.0)
        # The velocity actuators as plain numbers, read between batches (numpy's per-call cost
        # on arrays of two or three is most of a drive's time otherwise)
        self._actuated = [(k, int(acts[k]), float(self.gear[k]),
                           bool(model.actuator_ctrllimited[acts[k]]),
                           *(float(v) for v in model.actuator_ctrlrange[acts[k]]))
                          for k in range(len(acts)) if acts[k] >= 0]
        self._all_actuated = len(self._actuated) == len(acts)
        self.out = Outputs(index, model, idx[acts < 0])
        # The loop pushes the robot, not just the wheel: its gain counts the robot's mass as
        # each wheel carries it (m r^2 / wheels), or a 2 g wheel would not drag a 6 kg cart.
        self.reflected = 0.0
        if self.spec.kind == DIFF_DRIVE:
            root = index.entity_by_name[self.spec.entity].root_body
            self.reflected = (float(model.body_subtreemass[root]) * self.spec.radius ** 2
                              / len(names))
        torque = self.spec.max_wheel_torque
        if math.isfinite(torque):
            self.out.lo = np.maximum(self.out.lo, -torque)
            self.out.hi = np.minimum(self.out.hi, torque)
        self._index = index
        return True

    def apply(self, model: mujoco.MjModel, data: mujoco.MjData, kd: float) -> Optional[str]:
        """
        Drive toward the command; return what it needs next.

        :returns: :data:`EVERY_STEP` (a ramp, a velocity loop, a floating root's velocity),
            :data:`EVERY_BATCH` (velocity actuators hold the speeds: only the timeout is
            watched, between batches of steps) or None (stopped: nothing to do).
        """
        from .actuation import times_mass
        spec, cmd = self.spec, self.command
        fresh = cmd.timeout <= 0 or data.time - cmd.time <= cmd.timeout
        self._fresh = fresh
        vx, vy, wz = (cmd.vx, cmd.vy, cmd.wz) if fresh else (0.0, 0.0, 0.0)
        if spec.kind != PLANAR_FREE:
            vx, vy, wz = self._track(model, data, vx, vy, wz)
        if spec.kind == PLANAR_FREE:
            yaw = _body_yaw(data, model.dof_bodyid[self.free_dof])
            c, s = math.cos(yaw), math.sin(yaw)
            d = self.free_dof
            data.qvel[d], data.qvel[d + 1] = c * vx - s * vy, s * vx + c * vy
            data.qvel[d + 5] = wz
            return EVERY_STEP if fresh else None
        if spec.kind == DIFF_DRIVE:
            n = len(spec.left)
            half = wz * spec.separation / 2
            side = np.array([vx - half] * n + [vx + half] * (len(spec.wheels) - n))
            target = np.asarray(spec.signs) * side / spec.radius
            target = np.clip(target, -spec.max_wheel_speed, spec.max_wheel_speed)
            step = spec.max_wheel_acceleration * model.opt.timestep
            self.speeds = self.speeds + np.clip(target - self.speeds, -step, step)
        else:  # planar joints: the slides' velocities that move the base at (vx, vy)
            base = model.jnt_bodyid[self.jids[2]]
            yaw = _body_yaw(data, base)
            c, s = math.cos(yaw), math.sin(yaw)
            wx, wy = c * vx - s * vy, s * vx + c * vy
            (a0, a1), (b0, b1) = data.xaxis[self.jids[0]][:2], data.xaxis[self.jids[1]][:2]
            det = a0 * b1 - b0 * a1  # the two slides' axes: not parallel (found so)
            self.speeds = np.array([(wx * b1 - b0 * wy) / det, (a0 * wy - wx * a1) / det,
                                    wz * math.copysign(1.0, data.xaxis[self.jids[2]][2])])
            target = self.speeds
        changed = False
        for k, a, gear, limited, lo, hi in self._actuated:
            want = gear * float(self.speeds[k])
            ctrl = min(max(want, lo), hi) if limited else want
            if abs(ctrl - want) > 1e-9:
                self.saturated = True
            if data.ctrl[a] != ctrl:
                data.ctrl[a] = ctrl
                changed = True
        self.changed = changed
        if self._all_actuated:
            if spec.kind == DIFF_DRIVE and np.any(self.speeds != target):
                return EVERY_STEP  # a ramp runs
            return EVERY_BATCH if fresh or np.any(self.speeds) else None
        acts = self.act >= 0
        if (~acts).any():
            dof = self.out.dof
            err = self.speeds[~acts] - data.qvel[dof]
            # PI: a load (a dragging caster, a slope) leaves no lasting speed error, as a
            # velocity-controlled joint has none. Integral time 4 / kd; it stops growing while
            # the torque is at its limit.
            if self.integral is None or len(self.integral) != len(err):
                self.integral = np.zeros(len(err))
            u = kd * (err + kd / 4 * self.integral)
            tau = times_mass(model, data, dof, u) + self.reflected * u + data.qfrc_bias[dof]
            limited = self.out.write(data, tau)
            self.integral = np.where(limited, self.integral,
                                     self.integral + err * model.opt.timestep)
        if (~acts).any() or np.any(self.speeds != target):
            return EVERY_STEP  # a velocity loop holds the wheels, or a ramp runs
        return EVERY_BATCH if fresh or np.any(self.speeds) else None

    def _track(self, model: mujoco.MjModel, data: mujoco.MjData, vx: float, vy: float,
               wz: float) -> tuple:
        """
        Return the command corrected so that the base moves as commanded, in its frame.

        A wheel's speed is not the base's: casters drag, wheels slip (a skid-steer turns by
        slipping), a joint's friction loss holds back what its velocity actuator gives. An
        integral of the base's own velocity error (gain :data:`TRACK_GAIN`, measured at the
        base body in simulated time) adds what they take, within :data:`TRACK_LIMIT` times the
        command axis by axis; where that is not enough (or an actuator's range clips),
        :attr:`saturated` says so. A stopped command (zeros, or timed out) clears it: a base at
        rest is held by its wheels, not by a remembered correction.
        """
        now = float(data.time)
        dt = 0.0 if self._seen is None else min(max(now - self._seen, 0.0), TRACK_DT_MAX)
        self._seen = now
        want = (vx, 0.0 if self.spec.kind == DIFF_DRIVE else vy, wz)
        if not any(want):
            self.trim = [0.0, 0.0, 0.0]
            self.saturated = False
            return 0.0, 0.0, 0.0
        vel = self._vel  # [angular, linear] at the body's origin, world axes
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, self.body, vel, 0)
        yaw = _body_yaw(data, self.body)
        c, s = math.cos(yaw), math.sin(yaw)
        have = (c * vel[3] + s * vel[4], -s * vel[3] + c * vel[4], vel[2])
        out, trims, saturated = [], [], False
        for w, h, t in zip(want, have, self.trim):
            bound = TRACK_LIMIT * abs(w)
            t += TRACK_GAIN * (w - h) * dt
            if abs(t) > bound:
                saturated = saturated or w != 0.0
                t = math.copysign(bound, t)
            trims.append(t)
            out.append(w + t)
        self.trim, self.saturated = trims, saturated
        return out[0], out[1], out[2]

    def release(self, data: mujoco.MjData) -> None:
        """Stop what it wrote (the entity is gone or its joints changed)."""
        if self.spec.kind != PLANAR_FREE and self._index is not None:
            self.out.release(data)
            data.ctrl[self.act[self.act >= 0]] = 0


def _body_yaw(data: mujoco.MjData, body: int) -> float:
    return quat.yaw_of(data.xquat[body])


def check_command(vx: float, vy: float, wz: float) -> tuple:
    """Return a command as floats, or raise InvalidArgumentError (not finite, too large)."""
    from ..base.errors import InvalidArgumentError
    try:
        values = tuple(float(v) for v in (vx, vy, wz))
    except (TypeError, ValueError):
        values = (math.nan,) * 3
    if not all(math.isfinite(v) for v in values) or max(abs(values[0]), abs(values[1])) > \
            MAX_SPEED or abs(values[2]) > MAX_TURN:
        raise InvalidArgumentError(ERR_COMMAND.format(speed=MAX_SPEED, turn=MAX_TURN, vx=vx,
                                                      vy=vy, wz=wz))
    return values


@dataclass
class Command:
    """A velocity command in the base's frame, at simulated time `time`; 0 timeout: none."""

    vx: float = 0.0
    vy: float = 0.0
    wz: float = 0.0
    time: float = -math.inf
    timeout: float = COMMAND_TIMEOUT
