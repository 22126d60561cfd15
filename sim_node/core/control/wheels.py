"""
What a spawn gives a wheeled base that its model lacks: wheel actuators, and casters that roll.

Read from the spawned model's uncompiled spec before it is attached (``editor.attach``), by the
rules :mod:`.bases` uses to find a differential drive: a Gazebo drive plugin's joints, else
hinges whose names say wheel and left or right.
"""

import logging
import math
from typing import Optional

import mujoco
import numpy as np

from .bases import DIFF_DRIVE
from ..base import loads

log = logging.getLogger(__name__)

#: Seconds in which a base's wheel actuator (a Gazebo drive plugin's, whose drive trims the
#: base's own speed: :mod:`.drives`) brings the robot to speed.
WHEEL_TAU = 0.05
#: Time steps of the world in which a ros2_control velocity interface's wheel reaches its
#: commanded speed under the load it carries (its time constant): held as Gazebo holds a
#: joint's velocity command, a constraint its joint meets within its effort limit.
HOLD_STEPS = 1
#: The most that gain may be, times the wheel's own inertia over the time step: beyond about
#: 20 a wheel's contact and its implicit velocity loop ring (measured on a 1 kg two-wheeler
#: whose wheels weigh 0.1 kg: 40 drove it at 2.5 times its speed, 20 did not).
HOLD_RATIO = 12.0
#: What :func:`add_wheel_actuators` assumes when a model gives no masses or no wheel radius.
FALLBACK_MASS, FALLBACK_RADIUS = 20.0, 0.1
#: How far above the wheels' lowest point a fixed body's collision may end and still be a
#: caster (:func:`roll_casters`): this share of the wheels' radius, at least CASTER_REACH_MIN
#: metres (a caster written a few millimetres short of the floor the robot then tips onto).
CASTER_REACH, CASTER_REACH_MIN = 0.25, 0.005
#: Above a user's own contact settings (``editor.OWN_CONTACT_PRIORITY``, 1) and the world's.
CASTER_PRIORITY = 2


class Alone:
    """
    A spawned model compiled alone, once, when first asked (None: it does not compile alone).

    What the spawn's rules measure that only a compiled model knows (a mesh's extent, a
    joint's inertia), for :func:`roll_casters` and the position servos
    (:func:`~.interfaces.add_position_servos`) alike: one compile of the robot, not one each.
    The copy is taken when first asked; what is added to the spec later (actuators) changes
    neither geometry nor inertia.

    :param assets: meshes given in memory (a spec built in code).
    """

    def __init__(self, spec: mujoco.MjSpec, assets: Optional[dict] = None):
        self._spec, self._assets = spec, assets
        self._done, self._model = False, None

    @property
    def model(self) -> Optional[mujoco.MjModel]:
        if not self._done:
            self._done = True
            probe = self._spec.copy()
            if self._assets:
                probe.assets = {**probe.assets, **self._assets}
            # One thread, as the world's own compile (Design.built): the world steps meanwhile.
            probe.compiler.usethread = False
            try:
                self._model = probe.compile()
            except ValueError as exc:
                log.info('the spawned model does not compile alone (%s): no casters made to '
                         'roll, no position interface held', exc)
        return self._model


def wheel_joints(spec: mujoco.MjSpec, plugin: Optional[dict] = None) -> list:
    """
    Return a model's wheel joints as :func:`.bases.find` will drive them (left, then right), or [].

    Read from an uncompiled spec, by the same rules: the plugin's joints, else hinges whose
    names say wheel and left or right.
    """
    hinges = {j.name: j for j in spec.joints if j.type == mujoco.mjtJoint.mjJNT_HINGE}
    if plugin and plugin['kind'] == DIFF_DRIVE:
        left = [hinges[n] for n in plugin['left'] if n in hinges]
        right = [hinges[n] for n in plugin['right'] if n in hinges]
        if left and right:
            return left + right
    wheels = [j for n, j in hinges.items() if 'wheel' in n.lower()]
    left = [j for j in wheels if 'left' in j.name.lower()]
    right = [j for j in wheels if 'right' in j.name.lower()]
    return left + right if left and right else []


def add_wheel_actuators(spec: mujoco.MjSpec, plugin: Optional[dict] = None,
                        explicit: bool = False, only: Optional[set] = None,
                        timestep: Optional[float] = None) -> list:
    """
    Give each wheel of a spawned model that has no actuator a velocity actuator of its own.

    A wheel's speed is then held by MuJoCo (implicitly, under ``implicit`` and
    ``implicitfast``: stable at any gain), not by a torque computed in Python before every
    step: what a base costs is what its actuators cost. The load is the robot's mass as each
    wheel carries it (``m r^2 / wheels``). A ros2_control velocity interface's wheel (`only`)
    holds the commanded speed as Gazebo holds a joint's velocity command: its gain is that
    load over :data:`HOLD_STEPS` time steps (at most :data:`HOLD_RATIO` times the wheel's own
    inertia over a step), so it reaches its speed within a few steps and a load torque ``T``
    leaves an error of ``T / gain`` (a car's rear wheels scrubbing through a turn: under 2%,
    ``test/test_core_wheels.py``). A drive plugin's wheel settles in about :data:`WHEEL_TAU`,
    and its drive trims the base's speed. The torque is bounded by the joint's effort limit
    (URDF ``effort``) or the plugin's wheel torque. Under the explicit integrators (Euler's
    actuator gains, RK4) the gain is capped at the wheel's own inertia over the time step,
    where an explicit velocity loop stays stable.

    :param only: the wheels that may be driven (a ros2_control robot's: its velocity
        interfaces, whose own actuators this replaces, sized for a wheel's load; besides the
        wheels found by name, any of them that is a hinge turning a round body); the others
        roll freely. None: all.
    :param explicit: the world integrates actuator gains explicitly (Euler, RK4).
    :param timestep: the world's time step (default: the spawned model's own).
    :returns: the names of the actuators added (``<joint>_drive``).
    """
    step = timestep or spec.option.timestep
    wheels = wheel_joints(spec, plugin)
    if only is not None:
        # A velocity interface's wheel by what it is, whatever its name: a hinge turning a
        # round body (a bicycle's one rear wheel, a tricycle's front wheel say neither left
        # nor right, and carry the robot's weight all the same).
        named = {j.name for j in wheels}
        wheels = [j for j in wheels if j.name in only] + [
            j for j in spec.joints if j.name in only and j.name not in named and
            j.type == mujoco.mjtJoint.mjJNT_HINGE and _spec_wheel_radius(j.parent) > 0]
        replaced = {j.name for j in wheels}
        for act in [a for a in spec.actuators if a.target in replaced]:
            spec.delete(act)
    driven = {a.target for a in spec.actuators}
    wheels = [j for j in wheels if j.name not in driven]
    if not wheels:
        return []
    mass = sum(max(float(b.mass), 0.0) for b in spec.bodies) or FALLBACK_MASS
    added = []
    for j in wheels:
        radius = _spec_wheel_radius(j.parent) or FALLBACK_RADIUS
        inertia = max(0.5 * max(float(j.parent.mass), 0.01) * radius ** 2, 1e-6)
        load = max(mass * radius ** 2 / len(wheels), inertia)
        if only is None:
            kv = load / WHEEL_TAU
        else:
            own = max(loads.moved_inertia(j) + float(j.armature), inertia)
            kv = min(load / (HOLD_STEPS * step), HOLD_RATIO * own / step)
        if explicit:
            kv = min(kv, inertia / step)
        act = spec.add_actuator(name=f'{j.name}_drive', target=j.name,
                                trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_velocity(kv=kv)
        torque = plugin.get('max_torque') if plugin else None
        limited = j.actfrclimited != mujoco.mjtLimited.mjLIMITED_FALSE and \
            j.actfrcrange[1] > j.actfrcrange[0]
        if limited or torque:
            hi = min(float(j.actfrcrange[1]) if limited else math.inf, torque or math.inf)
            act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.forcerange = [-hi, hi]
        added.append(act.name)
    return added


def hold_velocities(spec: mujoco.MjSpec, joints: set, timestep: float,
                    explicit: bool = False) -> list:
    """
    Give the joints `joints` that have no actuator a stiff velocity actuator each.

    For joints a system commands by velocity that are no wheel (a car's steering, held on its
    angle's error as gz-sim holds it): the gain is :data:`HOLD_RATIO` times what the joint
    moves over a step, as a velocity interface's wheel without a load. Returns their names.
    """
    driven = {a.target for a in spec.actuators}
    added = []
    for j in spec.joints:
        if j.name not in joints or j.name in driven or j.type not in (
                mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            continue
        own = max(loads.moved_inertia(j) + float(j.armature), 1e-6)
        kv = HOLD_RATIO * own / timestep if not explicit else own / timestep
        act = spec.add_actuator(name=f'{j.name}_drive', target=j.name,
                                trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_velocity(kv=kv)
        added.append(act.name)
    return added


def roll_casters(spec: mujoco.MjSpec, plugin: Optional[dict] = None,
                 assets: Optional[dict] = None, alone: Optional[Alone] = None) -> list:
    """
    Make the fixed casters of a wheeled model roll: their contacts carry weight, not friction.

    A caster, ball or omni wheel that a URDF fixes to the base (no joint to turn on) would drag
    along the floor with the friction of a block; Gazebo users give such links zero friction
    (``<mu1>0</mu1>``), and so does this, to the same end. A caster is known by what it does:
    a body of a model with wheels (:func:`wheel_joints`), with no joint of its own, not a wheel
    and not the wheels' parent, whose colliding geometry reaches down to the floor the wheels
    stand on (its lowest point within :data:`CASTER_REACH` of the wheels' radius above their
    lowest point, the model as it is written, at rest). Its name does not matter: a mast, an
    arm's base or a sensor mount that cannot reach the floor is never one, whatever its
    shape or where its origin is.
    Its colliding geoms get ``condim`` 1 (a frictionless contact) with priority
    :data:`CASTER_PRIORITY`: MuJoCo mixes two geoms' condim by their maximum, and a contact
    takes the settings of the geom with the higher priority. ``WorldConfig.casters_roll``
    (the node's ``casters_roll``) turns the rule off.

    :param assets: meshes given in memory (a spec built in code), to measure the geometry.
    :param alone: the spec compiled alone, shared with the spawn's other rules (default: one
        of its own, from `assets`).
    :returns: the names of the bodies made casters.
    """
    wheels = wheel_joints(spec, plugin)
    if not wheels:
        return []
    low = _lowest_points(alone or Alone(spec, assets))
    wheel_bodies = {w.parent.name for w in wheels}
    floor = min((low[b] for b in wheel_bodies if b in low), default=None)
    if floor is None:
        return []
    radius = max(_spec_wheel_radius(w.parent) for w in wheels) or FALLBACK_RADIUS
    reach = floor + max(CASTER_REACH * radius, CASTER_REACH_MIN)
    base = wheels[0].parent.parent.name
    found = []
    for body in spec.bodies:
        if body.joints or body.name in ('world', base) or body.name in wheel_bodies:
            continue
        solid = [g for g in body.geoms if g.contype or g.conaffinity]
        if solid and low.get(body.name, math.inf) <= reach:
            for g in solid:  # a contact takes the condim of its higher-priority geom
                g.condim, g.priority = 1, CASTER_PRIORITY
            found.append(body.name)
    return found


def _lowest_points(alone: Alone) -> dict:
    """
    Return body name -> the lowest point (z) of its colliding geoms, the model at rest.

    From the model compiled alone (a mesh's extent is known only once compiled): each geom's
    bounding box in its frame, turned into the world's. {} when it does not compile.
    """
    model = alone.model
    if model is None:
        return {}
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    low: dict = {}
    for g in range(model.ngeom):
        if not (model.geom_contype[g] or model.geom_conaffinity[g]) or \
                model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE:
            continue
        rot = data.geom_xmat[g].reshape(3, 3)
        centre, half = model.geom_aabb[g][:3], model.geom_aabb[g][3:]
        z = float(data.geom_xpos[g][2] + rot[2] @ centre - np.abs(rot[2]) @ half)
        name = model.body(int(model.geom_bodyid[g])).name
        low[name] = min(low.get(name, math.inf), z)
    return low


def _spec_wheel_radius(body) -> float:
    """Return a wheel body's radius from its spec geoms (a cylinder's, a sphere's), or 0."""
    sizes = [float(g.size[0]) for g in body.geoms
             if g.type in (mujoco.mjtGeom.mjGEOM_CYLINDER, mujoco.mjtGeom.mjGEOM_SPHERE,
                           mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_ELLIPSOID)]
    return max(sizes, default=0.0)
