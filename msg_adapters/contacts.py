"""
A contact report as ros_gz_interfaces/msg/Contacts, the message Gazebo's contact sensor gives.

Per pair of collisions touching, one Contact: ``collision1`` the sensor's, ``collision2`` the
other, each an Entity of type COLLISION named ``model::link::collision`` with its geom id (of
the model generation the report was taken in); per contact point a position, a normal from
collision1 to collision2, a depth, and a JointWrench: ``body_1_wrench`` the force on
collision1's link, ``body_2_wrench`` its opposite (world frame, torques zero: about the point).
"""

from geometry_msgs.msg import Vector3
from ros_gz_interfaces.msg import Contact, Contacts, Entity, JointWrench
from sim_node.core.devices.contacts import ContactReport

from .convert import stamp


def contacts(report: ContactReport, scoped: tuple, frame: str) -> Contacts:
    """
    Return `report` as Contacts stamped with its simulated time.

    :param scoped: the report's model's geom names (``ModelInfo.geom_scoped``).
    :param frame: the world frame's name (positions, normals and forces are in it).
    """
    msg = Contacts()
    msg.header.stamp = stamp(report.time)
    msg.header.frame_id = frame
    for touch in report.touches:
        one = Contact()
        one.collision1 = _entity(touch.geom1, scoped)
        one.collision2 = _entity(touch.geom2, scoped)
        one.positions = [_vec(p) for p in touch.positions]
        one.normals = [_vec(n) for n in touch.normals]
        one.depths = [float(x) for x in touch.depths]
        for force in touch.forces:
            w = JointWrench()
            w.header = msg.header
            w.body_1_name.data = one.collision1.name.rsplit('::', 1)[0]
            w.body_2_name.data = one.collision2.name.rsplit('::', 1)[0]
            w.body_1_wrench.force = _vec(force)
            w.body_2_wrench.force = _vec(-force)
            one.wrenches.append(w)
        msg.contacts.append(one)
    return msg


def _entity(geom: int, scoped: tuple) -> Entity:
    out = Entity()
    out.id = int(geom)
    out.name = scoped[geom] if 0 <= geom < len(scoped) else f'geom{geom}'
    out.type = Entity.COLLISION
    return out


def _vec(v) -> Vector3:
    return Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))
