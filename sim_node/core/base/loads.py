"""
The loads a joint carries, read from an uncompiled spec: what a velocity it holds must move.

Used where an actuator is sized before the model compiles (the velocity interfaces of a
ros2_control robot, its wheels), so that a velocity command is held under load as Gazebo
holds it, and a stiff loop stays within what MuJoCo's implicit integration keeps stable.
"""

import mujoco
import numpy as np

from . import quat


def moved_inertia(joint: mujoco.MjsJoint) -> float:
    """
    Return the inertia a spec joint moves: what its body and every body below it weigh.

    For a slide, their masses (kg); for a hinge (or any other joint), their inertias about the
    joint's anchor (each body's mass times its distance squared, plus its largest principal
    moment: an upper bound of the moment about the axis, kg m^2). The model at rest; masses
    as the spec gives them (a URDF's inertials; an MJCF body whose mass its geoms give
    counts as 0 before it compiles).
    """
    slide = joint.type == mujoco.mjtJoint.mjJNT_SLIDE
    anchor = np.asarray(joint.pos, float)
    total = 0.0
    # Each body with its frame in the frame of the joint's own body.
    stack = [(joint.parent, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))]
    while stack:
        body, pos, rot = stack.pop()
        mass = max(float(body.mass), 0.0)
        if slide:
            total += mass
        else:  # URDF inertias arrive as fullinertia
            moment = max(float(np.max(body.inertia)), float(np.max(body.fullinertia[:3])))
            arm = pos + quat.rotate(rot, np.asarray(body.ipos, float)) - anchor
            total += moment + mass * float(arm @ arm)
        for child in body.bodies:
            stack.append((child, *quat.from_frame(pos, rot, np.asarray(child.pos, float),
                                                  np.asarray(child.quat, float))))
    return total
