"""
``ros2 run sim spawn``, as Gazebo's ``create``: from a file, a string or a description topic.

Run as a process against a running node, with the corpus's cart (a URDF with a Collada chassis
from its description package and a Gazebo diff-drive plugin); the launch example
(``launch/spawn_robot.launch.py``: robot_state_publisher, then ``sim spawn -topic``) runs
through ``test/launch_shim`` where ros2launch is not installed.
"""

import math
import os
from pathlib import Path
import subprocess
import sys

from conftest import ROOT, serve_node, wait_for, Watcher
import pytest

sys.path.insert(0, str(ROOT / 'ros_env'))
import corpus  # noqa: E402, I100

BOX = ('<mujoco><worldbody><body name="b"><freejoint/><geom type="box" size=".1 .1 .1"/>'
       '</body></worldbody></mujoco>')


@pytest.fixture(scope='module')
def own():
    return corpus.write_own(corpus.CORPUS / 'own')


@pytest.fixture(scope='module')
def node(own):
    yield from serve_node(f'resource_paths:=["{own}"]')


@pytest.fixture(scope='module')
def watch(node, rclpy_context):
    w = Watcher()
    yield w
    w.close()


def spawn(*args: str) -> subprocess.CompletedProcess:
    exe = Path(os.environ['SIM_PREFIX']) / 'lib' / 'sim' / 'spawn'
    return subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=120)


def cart(own: Path) -> Path:
    return own / 'cart_description' / 'urdf' / 'cart.urdf'


def yaw(state: dict) -> float:
    x, y, z, w = state['orientation_xyzw']
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def test_from_a_file_at_a_pose(sim, own):
    out = spawn('-file', str(cart(own)), '-name', 'cart_file', '-x', '1.5', '-y', '-1.0',
                '-z', '0.3', '-Y', '1.2')
    assert out.returncode == 0, out.stderr
    assert "spawned 'cart_file'" in out.stdout
    state = sim.entity_state('cart_file')
    assert state['position'][:2] == pytest.approx((1.5, -1.0), abs=0.05)
    assert yaw(state) == pytest.approx(1.2, abs=0.05)


def test_from_a_string(sim):
    out = spawn('-string', BOX, '-name', 'crate', '-x', '-1.0', '-z', '1.0')
    assert out.returncode == 0, out.stderr
    assert 'crate' in sim.entities()


def test_from_robot_description_as_robot_state_publisher_offers_it(sim, watch, own):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String
    text = cart(own).read_text()
    qos = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                     reliability=ReliabilityPolicy.RELIABLE)
    pub = watch.node.create_publisher(String, 'test_description', qos)
    pub.publish(String(data=text))  # published before the spawner starts: latched
    try:
        out = spawn('-topic', 'test_description', '-name', 'cart_topic', '-x', '-1.5',
                    '-y', '1.5', '-z', '0.3')
        assert out.returncode == 0, out.stderr
    finally:
        watch.node.destroy_publisher(pub)
    # it drives as its Gazebo plugin says, and describes itself with the URDF as given
    assert 'cart_topic' in sim.entities()
    published = watch.robot_description('cart_topic')
    assert 'libgazebo_ros_diff_drive.so' in published
    assert 'cart_topic/left_wheel_joint' in published


def test_a_topic_nobody_publishes_on_ends_with_a_clear_message(node):
    out = spawn('-topic', 'nobody_publishes_this', '-name', 'ghost', '-timeout', '2')
    assert out.returncode == 1
    assert "nothing was published on 'nobody_publishes_this' within 2 s" in out.stderr
    # said once, at the start: what it waits for and for how long
    assert out.stdout.count('waiting for a robot description on /nobody_publishes_this '
                            '(up to 2 s') == 1, out.stdout


def test_ctrl_c_while_waiting_ends_it_with_one_line_and_no_traceback(node):
    import signal
    exe = Path(os.environ['SIM_PREFIX']) / 'lib' / 'sim' / 'spawn'
    proc = subprocess.Popen([str(exe), '-topic', 'no_such_topic'], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    assert 'waiting for a robot description' in proc.stdout.readline()
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 130
    assert err.strip() == 'interrupted: nothing was spawned', err


def test_a_timeout_that_is_not_a_positive_number_is_refused(node):
    out = spawn('-topic', 'robot_description', '-timeout', '-1')
    assert out.returncode == 2 and '-timeout must be a positive number of seconds' in out.stderr


def test_a_name_in_use_exits_with_the_standards_code(sim):
    sim.spawn('taken', resource_string=BOX, position=(0.0, -2.0, 1.0))
    out = spawn('-string', BOX, '-name', 'taken')
    assert out.returncode == 101  # SpawnEntity.Response.NAME_NOT_UNIQUE
    assert 'spawn_entity answered 101' in out.stderr and 'taken' in out.stderr


def test_bad_arguments_say_what_is_expected(node):
    out = spawn('-name', 'nothing')
    assert out.returncode == 2 and 'one of the arguments -topic -file -string' in out.stderr


def test_the_launch_example_spawns_from_robot_state_publishers_topic(sim, own):
    out = subprocess.run([sys.executable, str(ROOT / 'test' / 'launch_shim' / 'run.py'),
                          str(ROOT / 'launch' / 'spawn_robot.launch.py'),
                          f'urdf:={cart(own)}', 'name:=cart_launch', 'x:=2.5', 'z:=0.3'],
                         capture_output=True, text=True, timeout=180, cwd=ROOT)
    assert out.returncode == 0, out.stdout + out.stderr
    wait_for(lambda: 'cart_launch' in sim.entities(), timeout=10)
    assert sim.entity_state('cart_launch')['position'][0] == pytest.approx(2.5, abs=0.05)


def test_a_concave_mesh_is_decomposed_while_the_world_steps_and_the_tool_says_so(sim, watch,
                                                                                 own):
    import random

    from diagnostic_msgs.msg import DiagnosticArray
    import concave_meshes
    # A washer of a shape no run made before: decomposed now, not read from the cache.
    folder = own / 'concave'
    folder.mkdir(exist_ok=True)
    washer = concave_meshes.ring(folder / 'washer.stl', segments=random.randint(60, 200))
    said = []
    sub = watch.node.create_subscription(DiagnosticArray, '/diagnostics', lambda msg: said.extend(
        kv.value for s in msg.status for kv in s.values if kv.key == 'decomposing'), 10)

    def now() -> float:
        # The node's simulated time as it answers now: the watcher's last /clock can lag by
        # seconds on a loaded host (it failed a full run reading 16 ms over a 1 s wait)
        return sim.entity_state(sim.entities()[0])['stamp']
    try:
        before = now()
        out = spawn('-file', str(washer), '-name', 'washer', '-x', '3.0', '-y', '-3.0')
        after = now()
    finally:
        watch.node.destroy_subscription(sub)
    assert out.returncode == 0, out.stderr
    assert 'splitting concave collision meshes' in out.stdout and 'washer.stl' in out.stdout
    assert any('washer.stl' in v for v in said), said
    # The world stepped while it waited (at real time: as long as the tool was told to wait).
    waited = float(said[-1].split('(')[1].split(' s')[0]) if said else 0.0
    assert after - before >= 0.5 * max(waited, 1.0), (before, after, said)
    peg = ('<mujoco><worldbody><body name="peg"><freejoint/><geom type="cylinder" '
           'size=".04 .1" mass=".1"/></body></worldbody></mujoco>')
    assert spawn('-string', peg, '-name', 'peg', '-x', '3.0', '-y', '-3.0',
                 '-z', '0.3').returncode == 0
    # Through the hole, on the floor (as its hull, the washer would hold it at 0.15 m).
    wait_for(lambda: sim.entity_state('peg')['position'][2] < 0.11, timeout=10)
