"""
``<entity>/robot_description`` over the wire, checked the way robot_state_publisher uses it.

For the default scene's robot, a spawned URDF arm and spawned Gymnasium models (hopper: a root
moved by joints of its own; ant: a free root), from a separate process: the URDF's forward
kinematics at the joint positions on ``joint_states``, placed at the root link's frame on
``/tf``, gives every link's ``/tf`` pose (``<entity>/<link>``) to 1 mm. The description is
latched (a late subscriber gets it), its meshes are files RViz can read, and it goes with
its entity.
"""

from pathlib import Path

from conftest import serve_node, wait_for, Watcher
import defusedxml.ElementTree as SafeET
import gymnasium
import numpy as np
import pytest
from test_core_description import ARM_URDF
from urdf_fk import urdf_fk

GYM_ASSETS = Path(gymnasium.__file__).parent / 'envs' / 'mujoco' / 'assets'


@pytest.fixture(scope='module')
def mesh_dir(tmp_path_factory):
    return tmp_path_factory.mktemp('meshes')


@pytest.fixture(scope='module')
def models(tmp_path_factory):
    """Write a one-joint robot whose link is a mesh (an icosphere, 320 faces)."""
    import trimesh
    folder = tmp_path_factory.mktemp('models')
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.1)
    (folder / 'ball.stl').write_bytes(sphere.export(file_type='stl'))
    (folder / 'pendulum.xml').write_text(
        '<mujoco><asset><mesh name="ball" file="ball.stl"/></asset><worldbody>'
        '<body name="base"><geom type="box" size=".05 .05 .05"/>'
        '<body name="bob" pos="0 0 -.3"><joint name="swing" axis="0 1 0" pos="0 0 .3"/>'
        '<geom type="mesh" mesh="ball"/></body></body></worldbody></mujoco>')
    return folder


@pytest.fixture(scope='module')
def node(mesh_dir, models):
    yield from serve_node(f'resource_paths:=["{GYM_ASSETS}", "{models}"]',
                          f'robot_description_mesh_dir:={mesh_dir}')


@pytest.fixture(scope='module')
def watch(node, rclpy_context):
    w = Watcher()
    yield w
    w.close()


def description(watch: Watcher, entity: str, timeout: float = 15.0) -> str:
    return watch.robot_description(entity, timeout)


def _matrix(q_xyzw) -> np.ndarray:
    x, y, z, w = q_xyzw
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def world_pose(frames: dict, frame: str) -> tuple:
    """Compose /tf and /tf_static from `frame` up to 'world': (position, rotation)."""
    p, r = np.zeros(3), np.eye(3)
    while frame != 'world':
        _, parent, xyz, q = frames[frame]
        p, r = np.asarray(xyz) + _matrix(q) @ p, _matrix(q) @ r
        frame = parent
    return p, r


def paused_and_settled(sim, watch: Watcher, link_frames: set) -> tuple:
    """Pause; return (joint positions, every frame) once both show the paused time."""
    sim.pause()

    def settled():
        js, clock = watch.joint_states, watch.latest_clock()
        if js is None or clock is None:
            return False
        stamp = js.header.stamp.sec + js.header.stamp.nanosec * 1e-9
        with watch.lock:  # the links' moving frames (others may be left from earlier worlds)
            stamps = {e[0] for f, e in watch.tf.items() if f in link_frames}
        return abs(stamp - clock) < 1e-9 and stamps == {clock}
    wait_for(settled, timeout=10)
    js = watch.joint_states
    with watch.lock:
        frames = {**watch.tf, **watch.tf_static}
    return dict(zip(js.name, js.position)), frames


def check_fk_matches_tf(sim, watch: Watcher, entity: str) -> int:
    text = description(watch, entity)
    root_link, fk = urdf_fk(text, {})
    joints, frames = paused_and_settled(sim, watch, {f'{entity}/{link}' for link in fk})
    try:
        root_link, fk = urdf_fk(text, joints)
        base_p, base_r = world_pose(frames, f'{entity}/{root_link}')
        compared = 0
        for link, (p, r) in fk.items():
            frame = f'{entity}/{link}'
            assert frame in frames, f'{link!r} of the description has no frame on /tf'
            want_p, want_r = world_pose(frames, frame)
            got_p, got_r = base_p + base_r @ p, base_r @ r
            assert np.linalg.norm(got_p - want_p) < 1e-3, (frame, got_p, want_p)
            assert np.abs(got_r - want_r).max() < 1e-3, frame
            compared += 1
        return compared
    finally:
        sim.play()


def _move_default_arms(watch: Watcher):
    """Command the default robot's four joints away from zero and wait until they are there."""
    from sensor_msgs.msg import JointState
    pub = watch.node.create_publisher(JointState, '/joint_commands', 10)
    cmd = JointState(name=['left_shoulder', 'left_elbow', 'right_shoulder', 'right_elbow'],
                     position=[0.7, -1.1, -0.4, 0.9])

    def moved():
        pub.publish(cmd)  # again until it is seen: the first may precede discovery
        js = watch.joint_states
        return js is not None and abs(js.position[list(js.name).index('left_elbow')] + 1.1) < 0.1
    try:
        wait_for(moved, timeout=15, interval=0.1)
    finally:
        watch.node.destroy_publisher(pub)


def test_the_default_robots_description_moves_as_tf_does(sim, watch):
    _move_default_arms(watch)
    assert check_fk_matches_tf(sim, watch, 'robot') == 5  # the root and four links


def test_a_spawned_urdf_is_described_by_its_own_text_and_matches_tf(sim, watch):
    sim.spawn('arm', resource_string=ARM_URDF, position=(2.0, 1.0, 0.0),
              orientation_xyzw=(0, 0, 0.6, 0.8))
    wait_for(lambda: watch.joint_states is not None and 'arm/elbow' in watch.joint_states.name)
    text = description(watch, 'arm')
    assert 'name="arm/shoulder"' in text and 'name="base_link"' in text
    assert check_fk_matches_tf(sim, watch, 'arm') == 5


def test_a_urdf_fixed_to_its_world_link_has_that_link_on_tf_where_the_urdf_puts_it(sim, watch):
    """The usual arm URDF: ``world`` -> base by a fixed joint, here off the origin and turned."""
    text = ARM_URDF.replace('<robot name="arm">', '<robot name="arm"><link name="world"/>'
                            '<joint name="anchor" type="fixed"><parent link="world"/>'
                            '<child link="base_link"/><origin xyz="0.2 -0.1 0.4" '
                            'rpy="0.2 -0.3 0.9"/></joint>')
    sim.spawn('fixed_arm', resource_string=text, position=(2.0, -1.0, 0.0),
              orientation_xyzw=(0, 0, 0.6, 0.8))
    try:
        wait_for(lambda: watch.joint_states is not None
                 and 'fixed_arm/elbow' in watch.joint_states.name)
        assert watch.links_without_frames('fixed_arm') == []
        # FK from the description's root (world) matches every link's frame on /tf
        assert check_fk_matches_tf(sim, watch, 'fixed_arm') == 6
        with watch.lock:  # and the world link is where the spawn put it
            frames = {**watch.tf, **watch.tf_static}
        p, r = world_pose(frames, 'fixed_arm/world')
        assert np.allclose(p, (2.0, -1.0, 0.0), atol=1e-6)
        assert np.allclose(r, _matrix((0, 0, 0.6, 0.8)), atol=1e-6)
    finally:
        sim.delete('fixed_arm')


@pytest.mark.parametrize('model', ['hopper', 'ant'])
def test_a_spawned_gymnasium_model_matches_tf(sim, watch, model):
    name = sim.spawn(model, uri=(GYM_ASSETS / f'{model}.xml').as_uri(), position=(-2, 3, 1.5))
    wait_for(lambda: watch.joint_states is not None
             and any(n.startswith(name + '/') for n in watch.joint_states.name))
    wait_for(lambda: 0.3 < (watch.latest_clock() or 0), timeout=10)
    assert check_fk_matches_tf(sim, watch, name) >= 4


def test_meshes_are_files_rviz_can_read_and_the_description_goes_with_its_entity(
        sim, watch, mesh_dir, models):
    import trimesh
    sim.spawn('pendulum', uri=(models / 'pendulum.xml').as_uri(), position=(3, -3, 1))
    text = description(watch, 'pendulum')
    meshes = [m.get('filename') for m in SafeET.fromstring(text).iter('mesh')]
    assert len(meshes) == 2  # the bob's visual and collision geometry: one file
    assert meshes[0] == meshes[1] and meshes[0].startswith(f'file://{mesh_dir}/')
    stl = trimesh.load(meshes[0][len('file://'):], file_type='stl')
    radius = np.linalg.norm(stl.vertices - stl.vertices.mean(axis=0), axis=1)
    assert len(stl.faces) == 320 and np.allclose(radius, 0.1, atol=1e-4)
    # an off-centre hinge: an intermediate link, on /tf_static at the anchor; the bob and it
    # match /tf (the root, the intermediate link, the bob)
    assert check_fk_matches_tf(sim, watch, 'pendulum') == 3
    sim.delete('pendulum')
    # Its description, controller state and trajectory action go with it.
    wait_for(lambda: not watch.node.get_publishers_info_by_topic('/pendulum/robot_description')
             and not watch.node.get_publishers_info_by_topic('/pendulum/controller_state')
             and not any(n.startswith('/pendulum/') for n, _ in
                         watch.node.get_service_names_and_types()))
    assert watch.node.get_publishers_info_by_topic('/robot/robot_description')


def test_the_launch_files_robot_model_display_reads_our_topic_and_frames(sim, watch):
    """``entity:=robot``: RViz's RobotModel reads the description and finds every link's frame."""
    from conftest import installed_prefix
    from sim_node.ros.topics.rviz_config import with_robot_model
    import yaml
    base = (installed_prefix() / 'share' / 'sim' / 'rviz' / 'sim.rviz').read_text()
    config = yaml.safe_load(with_robot_model(base, 'robot'))
    display = next(d for d in config['Visualization Manager']['Displays']
                   if d['Class'] == 'rviz_default_plugins/RobotModel')
    topic = display['Description Topic']
    assert topic['Durability Policy'] == 'Transient Local'
    assert dict(watch.node.get_topic_names_and_types())[topic['Value']] == ['std_msgs/msg/String']
    links = [link.get('name') for link in
             SafeET.fromstring(description(watch, 'robot')).findall('link')]
    with watch.lock:
        frames = {**watch.tf, **watch.tf_static}
    # RViz joins its TF prefix and a link name with '/'
    assert all(f"{display['TF Prefix']}/{link}" in frames for link in links), links
    others = [d for d in config['Visualization Manager']['Displays']
              if d['Class'] != 'rviz_default_plugins/RobotModel']
    assert others == yaml.safe_load(base)['Visualization Manager']['Displays']
