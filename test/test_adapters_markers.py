"""Markers follow the model generation: what RViz shows after each message is exactly the
geoms of the model that message came from, whatever was deleted or respawned under which
name in between."""

from visualization_msgs.msg import Marker

from conftest import DEFAULT_SCENE
from msg_adapters import markers
from sim_node.core import sources
from sim_node.core.world import World

THREE_GEOMS = '''<mujoco><worldbody><body name="b"><freejoint/>
  <geom type="box" size=".05 .05 .05"/><geom type="sphere" size=".04" pos="0 0 .1"/>
  <geom type="capsule" size=".02" fromto="0 0 .15 0 0 .3"/></body></worldbody></mujoco>'''


def apply(shown: dict, msg) -> dict:
    """What an RViz MarkerArray display holds after receiving `msg`."""
    for m in msg.markers:
        if m.action == Marker.DELETEALL:
            shown.clear()
        elif m.action == Marker.DELETE:
            shown.pop((m.ns, m.id), None)
        else:
            shown[(m.ns, m.id)] = m
    return shown


def test_a_respawn_with_fewer_geoms_leaves_no_stale_markers():
    w = World.from_file(str(DEFAULT_SCENE))
    w.spawn('thing', sources.from_model_text(THREE_GEOMS), position=[2, 0, 0.5])
    shown = apply({}, markers.markers(w.model_info, w.time, 'world'))
    assert len([k for k in shown if k[0] == 'sim/thing']) == 3
    # Within one publishing tick: deleted, and respawned under the same name with one geom.
    w.delete('thing')
    w.spawn('thing', sources.primitive('sphere', [0.05]), position=[2, 0, 0.5])
    info = w.model_info
    shown = apply(shown, markers.markers(info, w.time, 'world'))
    assert len([k for k in shown if k[0] == 'sim/thing']) == 1
    assert len(shown) == len(info.geoms)


def test_cleared_markers_leave_nothing():
    w = World.from_file(str(DEFAULT_SCENE))
    shown = apply({}, markers.markers(w.model_info, w.time, 'world'))
    assert shown
    assert apply(shown, markers.clear_markers(w.time, 'world')) == {}
