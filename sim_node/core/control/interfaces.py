"""
A ros2_control robot's position interfaces, held as gz_ros2_control holds them.

gz_ros2_control commands a joint's position as a joint velocity command, refreshed at each
update of its controller manager: ``position_proportional_gain x update_rate x (command -
position)`` (its plugin's ``<position_proportional_gain>``, default 0.1), which Gazebo then
holds as a constraint, whatever the joint carries, within its effort limit. A first-order lag
of time constant ``1 / (gain x update_rate)`` (0.1 s at 100 Hz) that no load pushes off.

Here the same law is one MuJoCo position actuator per position interface, added at spawn
(:func:`add_position_servos`): its force ``kv (gain x rate x (command - q) - qdot)`` is
``kp (command - q) - kv qdot`` with ``kp = kv x gain x rate``, so a position command is the
actuator's control, whatever writes it (a controller, a trajectory, a hold). ``kv``, the
velocity hold, is integrated implicitly and set as stiff as a wheel's velocity interface
(:data:`.wheels.HOLD_RATIO` times the joint's own inertia over a step); ``kp`` acts explicitly,
so it is kept within :data:`KP_BOUND` times the joint's inertia over a step squared (at high
update rates ``kv`` gives way, and the law's time constant stays the plugin's). The joint's
inertia is read from the robot compiled alone, at rest (MuJoCo's ``dof_invweight0``: about
its axis, with what it carries and its other joints free). ROS-free; called on the spawn's
uncompiled spec.
"""

import logging
import math
from typing import Iterable, Optional

import mujoco

from . import wheels
from .manager import DEFAULT_UPDATE_RATE
from ..base.records import EFFORT

log = logging.getLogger(__name__)

#: The most a position servo's explicit stiffness may be, times the joint's inertia over the
#: time step squared (a spring integrated explicitly rings from about 4; at rest a joint's
#: inertia can be several times what it is elsewhere in its range).
KP_BOUND = 0.3
_ONE_DOF = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
#: How a position servo's actuator is named after its joint (``<joint>_gz_position``): no
#: other actuator is let go (:class:`Servos`).
SERVO_SUFFIX = '_gz_position'


def add_position_servos(spec: mujoco.MjSpec, control, timestep: float, explicit: bool = False,
                        alone: Optional[wheels.Alone] = None) -> list:
    """
    Give each position interface of a gz_ros2_control robot its position servo.

    A joint whose command interfaces include position and not velocity (one with a velocity
    interface is held by its velocity, as gz_ros2_control's write() prefers velocity) and
    that has no actuator of its own. The torque stays within the URDF's effort limit.

    :param control: its :class:`~sim_node.core.models.ros2_control.Ros2Control`, with the
        plugin's ``position_gain`` and the controller manager's ``update_rate`` (None: the
        manager's default, 100 Hz).
    :param explicit: the world integrates actuator gains explicitly (Euler, RK4): the
        velocity hold is kept within the joint's inertia over the step.
    :param alone: the spec compiled alone (:class:`.wheels.Alone`), shared with the spawn's
        other rules (default: one of its own).
    :returns: the names of the actuators added (``<joint>`` and :data:`SERVO_SUFFIX`).
    """
    if control is None or not control.simulated:
        return []
    driven = {a.target for a in spec.actuators}
    joints = [spec.joint(name) for name, j in control.joints().items()
              if 'position' in j.command and 'velocity' not in j.command and
              name not in driven and spec.joint(name) is not None]
    joints = [j for j in joints if int(j.type) in _ONE_DOF]
    if not joints:
        return []
    inertia = _joint_inertias(alone or wheels.Alone(spec))
    rate = float(control.update_rate or DEFAULT_UPDATE_RATE)
    law = control.position_gain * rate  # 1/s: the lag's rate
    added = []
    for j in joints:
        own = inertia.get(j.name)
        if own is None or not own > 0:
            continue
        kv = wheels.HOLD_RATIO * own / timestep
        if explicit:
            kv = min(kv, own / timestep)
        kp = kv * law
        if kp * timestep ** 2 > KP_BOUND * own:
            kp = KP_BOUND * own / timestep ** 2
            kv = kp / law
        act = spec.add_actuator(name=f'{j.name}{SERVO_SUFFIX}', target=j.name,
                                trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_position(kp=kp, kv=kv)
        if j.actfrclimited != mujoco.mjtLimited.mjLIMITED_FALSE and \
                j.actfrcrange[1] > j.actfrcrange[0]:
            hi = float(j.actfrcrange[1])
            act.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.forcerange = [-hi, hi]
        added.append(act.name)
    return added


def stiffen_mimics(spec: mujoco.MjSpec, timestep: float) -> None:
    """
    Make a URDF's ``<mimic>`` joints follow their leader as Gazebo's do: without give.

    MuJoCo reads a mimic as a joint equality with the default ``solref`` (a 0.02 s spring):
    a gripper's mimicking finger, pressed by its leader's 50 N on a block, gave 15 mm. Its
    time constant becomes two time steps, the stiffest MuJoCo keeps stable.
    """
    for eq in spec.equalities:
        if eq.type == mujoco.mjtEq.mjEQ_JOINT:
            eq.solref = [2.0 * timestep, 1.0]


def stiffen_limits(spec: mujoco.MjSpec, timestep: float) -> None:
    """
    Make joints' stops as hard as a step allows, as SDF's (``<limit><stiffness>``: 1e8).

    MuJoCo's default stop is a 0.02 s spring: a hinge run into it at 5 rad/s went 0.035 rad
    past; with a time constant of two steps, a few thousandths.
    """
    for j in spec.joints:
        if j.limited == mujoco.mjtLimited.mjLIMITED_TRUE:
            j.solref_limit = [2.0 * timestep, 1.0]


def _joint_inertias(alone: wheels.Alone) -> dict:
    """
    Return joint name -> its inertia at rest (kg m^2 or kg), from the spec compiled alone.

    MuJoCo's ``dof_invweight0`` inverted: the inertia a push on the joint meets at the model's
    rest pose with its other joints free (the least it can be: what an explicit gain must
    stay stable on). {} when it does not compile alone.
    """
    model = alone.model
    if model is None:
        return {}
    out = {}
    for j in range(model.njnt):
        dof = int(model.jnt_dofadr[j])
        if dof >= 0 and int(model.jnt_type[j]) in _ONE_DOF:
            weight = float(model.dof_invweight0[dof])
            if math.isfinite(weight) and weight > 0:
                out[model.joint(j).name] = 1.0 / weight
    return out


class Servos:
    """
    Which position servos hold their joints, and which are let go, as in Gazebo.

    A gz_ros2_control joint moves by its command: none (``<hold_joints>false`` and no
    controller) or an effort command leaves it free, a position or velocity command holds it.
    A servo holds from its joint's first position or velocity command (a hold at spawn, a
    controller's, a trajectory's) until an effort command; until then its gains are 0 in the
    live model (its compiled gains come back on a recompile, and are taken off again at the
    binding that follows). Kept by the world's commands, its lock held.
    """

    def __init__(self):
        self.engaged: set = set()  # joint names whose servo holds
        self._model = None  # the model whose compiled gains _gains holds
        self._gains: dict = {}  # actuator -> (joint name, kp, -kv) as compiled

    def command(self, name: str, mode: str) -> bool:
        """Take a command to joint `name` in `mode`; return whether its servo's hold changed."""
        before = name in self.engaged
        if mode == EFFORT:
            self.engaged.discard(name)
        else:
            self.engaged.add(name)
        return before != (name in self.engaged)

    def engage(self, names: Iterable[str]) -> None:
        self.engaged.update(names)

    def apply(self, model: mujoco.MjModel) -> None:
        """Give the servos of `model` their gains: as compiled where engaged, else 0."""
        if model is not self._model:
            self._model = model
            # A joint deleted is forgotten: a robot spawned again under its name starts free.
            self.engaged &= {model.joint(j).name for j in range(model.njnt)}
            self._gains = {
                a: (model.joint(int(model.actuator_trnid[a, 0])).name,
                    float(model.actuator_gainprm[a, 0]), float(model.actuator_biasprm[a, 2]))
                for a in range(model.nu) if model.actuator(a).name.endswith(SERVO_SUFFIX)}
        for a, (joint, kp, damping) in self._gains.items():
            on = joint in self.engaged
            model.actuator_gainprm[a, 0] = kp if on else 0.0
            model.actuator_biasprm[a, 1] = -kp if on else 0.0
            model.actuator_biasprm[a, 2] = damping if on else 0.0

    def settle(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Make the holding servos of `model` (:meth:`apply` first) hold where they are."""
        for a, (joint, _, _) in self._gains.items():
            if joint in self.engaged:
                data.ctrl[a] = data.qpos[model.jnt_qposadr[int(model.actuator_trnid[a, 0])]]
