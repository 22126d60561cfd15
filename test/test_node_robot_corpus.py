"""
Robot files as users bring them, over the wire.

Every file of the corpus (``ros_env/corpus.py``: arms, hands, a humanoid, a legged robot, a dog
with a skinned mesh, a kitchen with furniture, from robosuite, gymnasium-robotics and
dm_control) is spawned by ``file://`` URI into the running default scene with the corpus folder
in resource_paths, seen with its joints on joint_states and finite frames on /tf, and deleted.
The built-in spawnables stay readable beside resource_paths, and an entity with many sensors
and a camera comes and goes 200 times without taking the node down.
"""

import math
from pathlib import Path
import sys

from conftest import serve_node, wait_for, Watcher
import mujoco
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'ros_env'))
import corpus  # noqa: E402, I100

ONE_DOF = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


@pytest.fixture(scope='module')
def corpus_folder():
    return corpus.fetch()


@pytest.fixture(scope='module')
def node(corpus_folder):
    yield from serve_node(f'resource_paths:=["{corpus_folder}"]', 'real_time_factor:=0.0')


@pytest.fixture(scope='module')
def watch(node, rclpy_context):
    w = Watcher()
    yield w
    w.close()


@pytest.mark.parametrize('model', corpus.MODELS, ids=[m.name for m in corpus.MODELS])
def test_every_corpus_file_spawns_moves_and_goes(node, watch, sim, model):
    bare = mujoco.MjModel.from_xml_path(str(model.file))  # what bare MuJoCo makes of it
    n_joints = sum(1 for j in range(bare.njnt) if int(bare.jnt_type[j]) in ONE_DOF)
    name = sim.spawn('robot_' + model.name.replace('-', '_'), uri=model.file.as_uri(),
                     position=(4.0, 4.0, 3.0))
    try:
        def joints_listed():
            js = watch.joint_states
            return js is not None and sum(n.startswith(name + '/') for n in js.name) == n_joints
        wait_for(joints_listed, timeout=15)

        def own_frames():
            with watch.lock:
                return {f: e for f, e in {**watch.tf, **watch.tf_static}.items()
                        if f == name or f.startswith(name + '/')}
        wait_for(lambda: name in own_frames(), timeout=15)
        for frame, (_, _, xyz, q) in own_frames().items():
            assert all(math.isfinite(v) for v in xyz + q), frame
        # Every link of its robot_description has a frame (RViz's RobotModel needs them all).
        assert watch.links_without_frames(name) == []
    finally:
        sim.delete(name)
    assert name not in sim.entities()


def test_builtin_spawnables_stay_readable_beside_resource_paths(node, sim):
    name = sim.spawn('crate_beside_corpus', uri='box', position=(-3.0, -3.0, 0.5))
    assert name == 'crate_beside_corpus' and name in sim.entities()
    sim.delete(name)
    assert name not in sim.entities()


def test_a_file_outside_the_corpus_is_still_refused_through_dotdot(node, sim, corpus_folder):
    from sim_node.ros.client import SimServiceError
    from simulation_interfaces.srv import SpawnEntity
    outside = f'{corpus_folder}/robosuite/../../../scenes/default.xml'  # the source tree's
    with pytest.raises(SimServiceError) as err:
        sim.spawn('escapee', uri=f'file://{outside}')
    assert err.value.code == SpawnEntity.Response.MISSING_ASSETS
    assert 'not inside the directories' in err.value.message


SENSORY = """<mujoco model="sensory">
  <worldbody>
    <body name="base" pos="0 0 0.2">
      <freejoint/>
      <geom type="box" size="0.2 0.2 0.05"/>
      <camera name="eye" pos="0 0 0.1" xyaxes="1 0 0 0 1 0"/>
      {sites}
      <body name="flap" pos="0 0 0.1"><joint name="hinge" axis="0 1 0"/>
        <geom type="box" size="0.05 0.05 0.01" pos="0.1 0 0"/></body>
    </body>
  </worldbody>
  <sensor>{sensors}</sensor>
</mujoco>
"""


def test_an_entity_with_many_sensors_and_a_camera_comes_and_goes_200_times(node, watch, sim):
    """
    Publishers and action servers come and go under a busy executor: the node lives (19, #5).

    The entity has 40 touch sensors, a camera and a hinge (so a follow_joint_trajectory action
    server of its own).
    """
    sites = ''.join(f'<site name="s{i}" pos="{0.01 * i} 0 0.05" size="0.01"/>'
                    for i in range(40))
    sensors = ''.join(f'<touch name="t{i}" site="s{i}"/>' for i in range(40))
    text = SENSORY.format(sites=sites, sensors=sensors)
    # Subscribers on the entity's own topics, there before it comes and after it goes.
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import Image
    from std_msgs.msg import Float64MultiArray
    got = {'values': 0, 'image': 0}
    for k in range(0, 40, 8):
        watch.node.create_subscription(
            Float64MultiArray, f'sensors/sensory/t{k}/values',
            lambda _: got.__setitem__('values', got['values'] + 1), qos_profile_sensor_data)
    watch.node.create_subscription(Image, 'cameras/sensory/eye/image_raw',
                                   lambda _: got.__setitem__('image', got['image'] + 1),
                                   qos_profile_sensor_data)
    for i in range(200):
        name = sim.spawn('sensory', resource_string=text, position=(3.0, -3.0, 0.5))
        sim.delete(name)
        assert node.proc.poll() is None, f'the node died after {i + 1} cycles'
    assert 'sensory' not in sim.entities()  # still answering
    assert 'InvalidHandle' not in node.output()
    assert got['values'] > 0  # the subscribers heard the entity while it was there
