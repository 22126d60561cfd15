"""
Shared fixtures.

Every test session keeps DDS discovery on loopback and uses its own ROS_DOMAIN_ID, so parallel runs
on one machine never meet.
"""

import collections
import os
from pathlib import Path
import random
import signal
import subprocess
import sys
import tempfile
import time

import pytest

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('SIM_TEST_DOMAIN_ID', str(random.SystemRandom().randint(1, 100)))
os.environ['ROS_DOMAIN_ID'] = os.environ['SIM_TEST_DOMAIN_ID']
# Converted meshes are cached in a folder of this test session (and of the nodes it starts),
# not in the user's ~/.cache: every run converts from scratch once.
os.environ.setdefault('SIM_MESH_CACHE', tempfile.mkdtemp(prefix='sim_test_mesh_cache_'))

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / 'scenes'
DEFAULT_SCENE = SCENES / 'default.xml'


#: Test files whose tests start node processes or run long: marked `slow` (``make test-fast``
#: leaves them out; ``make test`` runs everything).
SLOW_FILES = ('test_node_', 'test_adversarial_node', 'test_readme_examples',
              'test_examples_tutorials', 'test_conformance')


def pytest_collection_modifyitems(config, items):
    for item in items:
        if item.path.name.startswith(SLOW_FILES):
            item.add_marker(pytest.mark.slow)


#: A two-joint arm without actuators (PD drives it), 1 kg links of 0.3 m, for trajectory tests.
TWO_JOINT_ARM = """<mujoco><worldbody><body name="base"><geom type="box" size="0.05 0.05 0.05"/>
  <body name="upper" pos="0 0 0.2"><joint name="j1" axis="0 1 0"/>
    <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/>
    <body name="lower" pos="0.3 0 0"><joint name="j2" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1"/></body></body>
  </body></worldbody></mujoco>"""


def installed_prefix() -> Path:
    prefix = os.environ.get('SIM_PREFIX')
    if not prefix:
        pytest.skip('SIM_PREFIX is not set: run the tests with `make test`')
    return Path(prefix)


def node_executable() -> Path:
    """Return the very file `ros2 run sim node` starts."""
    return installed_prefix() / 'lib' / 'sim' / 'node'


def _end_with_parent() -> None:
    """
    In the child before it starts: SIGTERM when the test process dies (Linux).

    A test run killed midway otherwise leaves its nodes running, in its domain, for minutes: a
    later run's nodes then meet one and, as the second simulator of that name, exit at start.
    """
    import ctypes
    try:
        ctypes.CDLL('libc.so.6', use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except OSError:
        pass


class NodeProcess:
    """The installed node executable running as a subprocess."""

    def __init__(self, *params: str, namespace: str = '', remaps: tuple = (),
                 program: tuple = ()):
        """`program`: what to run instead of the node executable (a script that wraps it)."""
        args = [*(program or (str(node_executable()),)), '--ros-args']
        for p in params:
            args += ['-p', p]
        if namespace:
            args += ['-r', f'__ns:={namespace}']
        for r in remaps:
            args += ['-r', r]
        self.log_path = (Path(os.environ.get('TMPDIR', '/tmp'))
                         / f'sim_node_{os.getpid()}_{id(self)}.log')
        self._log = open(self.log_path, 'w+')
        self.proc = subprocess.Popen(args, stdout=self._log, stderr=subprocess.STDOUT,
                                     start_new_session=True, preexec_fn=_end_with_parent)

    def output(self) -> str:
        self._log.flush()
        return self.log_path.read_text()

    def interrupt(self, timeout: float = 5.0) -> tuple:
        """SIGINT; returns (exit code, seconds it took to exit)."""
        t0 = time.monotonic()
        self.proc.send_signal(signal.SIGINT)
        try:
            code = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            code = self.proc.wait()
        return code, time.monotonic() - t0

    def close(self) -> None:
        if self.proc.poll() is None:
            self.interrupt()
        self._log.close()


def serve_node(*params: str):
    """
    Run a node for the length of a module's `node` fixture, which yields from this.

    At the end it must exit cleanly on SIGINT.
    """
    proc = NodeProcess(*params)
    yield proc
    code, _ = proc.interrupt()
    assert code == 0, proc.output()


@pytest.fixture(scope='session')
def rclpy_context():
    import rclpy
    rclpy.init()
    try:
        yield
    finally:
        rclpy.try_shutdown()


@pytest.fixture
def start_node():
    """Start node processes (parameters as 'name:=value' strings); all stopped at the end."""
    procs = []

    def start(*params, namespace='', remaps=(), program=()):
        p = NodeProcess(*params, namespace=namespace, remaps=remaps, program=program)
        procs.append(p)
        return p
    yield start
    for p in procs:
        p.close()


@pytest.fixture(scope='module')
def module_client(node, rclpy_context):
    """One client for a module that starts its own `node`: discovery happens once."""
    from sim_node.ros.client import SimClient
    c = SimClient(timeout_sec=30)
    yield c
    c.close()


@pytest.fixture
def sim(module_client):
    """Return the module's client with its world reset (spawned entities too) and playing."""
    from simulation_interfaces.msg import SimulationState
    module_client.reset()
    if module_client.state() != SimulationState.STATE_PLAYING:
        module_client.play()
    return module_client


@pytest.fixture
def client(rclpy_context):
    from sim_node.ros.client import SimClient
    c = SimClient()
    yield c
    c.close()


def write_mesh_model(folder: Path, faces: int, meshes: int = 1) -> Path:
    """
    Write an MJCF model of a body with `meshes` meshes of `faces` faces into `folder`.

    Slow to compile: MuJoCo processes each mesh (its hull, its inertia) on its own.
    """
    import trimesh
    sphere = trimesh.creation.icosphere(subdivisions=7)  # 327,680 faces to cut from
    mesh = trimesh.Trimesh(sphere.vertices, sphere.faces[:faces], process=False)
    (folder / 'big.stl').write_bytes(mesh.export(file_type='stl'))
    assets = ''.join(f'<mesh name="m{k}" file="big.stl" scale="{1 + k * 0.01} 1 1"/>'
                     for k in range(meshes))
    geoms = ''.join(f'<geom type="mesh" mesh="m{k}"/>' for k in range(meshes))
    (folder / 'big.xml').write_text(
        f'<mujoco><asset>{assets}</asset><worldbody><body name="b">'
        f'<freejoint/>{geoms}</body></worldbody></mujoco>')
    return folder / 'big.xml'


class Ticker:
    """
    A thread ticking every millisecond while a block runs; ``held``: its longest wait (s).

    What a call that holds the GIL costs every other thread of the process (the stepping
    loop's): a call that lets the GIL go leaves the ticks a millisecond or two apart.
    ``spent``: the block's wall time.
    """

    def __enter__(self) -> 'Ticker':
        import threading
        self._ticks, self._done = [time.perf_counter()], threading.Event()
        self._thread = threading.Thread(target=self._tick)
        self._thread.start()
        self._t0 = time.perf_counter()
        return self

    def _tick(self) -> None:
        while not self._done.is_set():
            time.sleep(0.001)
            self._ticks.append(time.perf_counter())

    def __exit__(self, *exc) -> None:
        self.spent = time.perf_counter() - self._t0
        self._done.set()
        self._thread.join()
        t = self._ticks
        self.held = max((b - a for a, b in zip(t, t[1:]) if b >= self._t0), default=0.0)


#: How long a call may take before a test calls it hung: what would block for ever (a FIFO, a
#: catastrophic pattern, a hostile file) is caught, and a busy host is never mistaken for one.
#: It is no speed claim: how fast things are is measured by the benchmarks' verdicts.
HANG_SEC = 30.0


def returns(call, timeout: float = HANG_SEC):
    """
    Call `call()` on a thread; return its value (or raise its error) once it has returned.

    :raises AssertionError: it had not returned after `timeout` seconds (it hangs).
    """
    import threading
    out: dict = {}

    def run():
        try:
            out['value'] = call()
        except BaseException as exc:  # noqa: B902 (handed to the caller)
            out['error'] = exc
    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(timeout)
    assert not thread.is_alive(), f'{call!r} did not return within {timeout} s: it hangs'
    if 'error' in out:
        raise out['error']
    return out.get('value')


def mcap_records_until_cut(path: Path) -> list:
    """Every (topic, log time) of an MCAP file read as a stream, up to where it was cut."""
    from mcap.records import Channel, Message
    from mcap.stream_reader import StreamReader
    channels, out = {}, []
    with open(path, 'rb') as stream:
        try:
            for record in StreamReader(stream).records:
                if isinstance(record, Channel):
                    channels[record.id] = record.topic
                elif isinstance(record, Message):
                    out.append((channels[record.channel_id], record.log_time))
        except Exception:  # noqa: B902 (the cut: a record torn in half)
            pass
    return out


def wait_for(predicate, timeout: float = 10.0, interval: float = 0.05):
    """Poll until predicate() is truthy; returns its value or raises AssertionError."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f'condition not met within {timeout} s')
        time.sleep(interval)


def heard(watch, msg_type, topic: str, n: int = 2, timeout: float = 20.0,
          reliable: bool = False) -> list:
    """
    Return the messages `watch` hears on `topic` until it has `n` of them (at most `timeout` s).

    With the sensor data QoS (best effort: every publisher matches), or `reliable` (depth 100:
    none of a burst is lost, but a best-effort publisher does not match).
    """
    from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE) if reliable \
        else qos_profile_sensor_data
    got = []
    sub = watch.node.create_subscription(msg_type, topic, got.append, qos)
    try:
        wait_for(lambda: len(got) >= n, timeout=timeout)
    finally:
        watch.node.destroy_subscription(sub)
    return got


sys.path.insert(0, str(Path(__file__).resolve().parent))


#: Transforms a Watcher counts repeats over: about 20 s of the default scene's /tf at 100 Hz.
TF_SENDS_KEPT = 20_000


def action_client(node, action_type, name: str, **kwargs):
    """
    Return an rclpy ActionClient on `node` whose requests cannot lose their responses.

    Jazzy's ``ActionClient.send_goal_async`` sends the request, then files the future its
    response will complete. A node spun on another thread (a :class:`Watcher`'s) can take the
    response in between: rclpy logs "Ignoring unexpected goal response" and the future never
    completes (test_node_trajectory, in CI; the node answers within a millisecond). The
    result and cancel requests are made the same way. Here each request is made while the
    node's spinning thread waits (its Watcher's ``spin_lock``, at most one spin of 50 ms).
    A node spun on the calling thread, as SimClient's, has no such race.
    """
    from rclpy.action import ActionClient

    guard = getattr(node, 'sim_test_spin_lock', None)

    class Guarded(ActionClient):

        def send_goal_async(self, *args, **kw):
            with guard:
                return super().send_goal_async(*args, **kw)

        def _get_result_async(self, *args, **kw):
            with guard:
                return super()._get_result_async(*args, **kw)

        def _cancel_goal_async(self, *args, **kw):
            with guard:
                return super()._cancel_goal_async(*args, **kw)

    return (ActionClient if guard is None else Guarded)(node, action_type, name, **kwargs)


class Watcher:
    """Subscribes, in the test process, to what the node publishes; spins on its own thread."""

    def __init__(self, namespace: str = ''):
        import threading

        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import JointState
        from tf2_msgs.msg import TFMessage
        from visualization_msgs.msg import MarkerArray

        ns = namespace.rstrip('/') + '/' if namespace else ''
        self.node = rclpy.create_node(f'watcher_{id(self):x}')
        self.lock = threading.Lock()
        self.clock = []
        self.tf = {}  # child frame -> (stamp sec, parent, (x, y, z), (qx, qy, qz, qw))
        self.tf_stamps = []  # per /tf message: the set of stamps in it
        #: (child frame, stamp) of the newest transforms received (see tf_sends). Bounded: a
        #: module that runs for minutes with robots on /tf at 100 Hz would otherwise keep
        #: millions of them, and this process would slow down with its garbage collections.
        self._sends = collections.deque(maxlen=TF_SENDS_KEPT)
        self.tf_static = {}
        self.markers = {}  # (ns, id) -> marker
        self.joint_states = None
        self.heard: dict = {}  # topic kind -> wall time (monotonic) it was last heard
        self.spin_errors: list = []  # what spinning raised (and went on from)
        latched = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE)
        n = self.node
        n.create_subscription(Clock, '/clock', self._on_clock, 100)
        n.create_subscription(TFMessage, '/tf', self._on_tf, 100)
        n.create_subscription(TFMessage, '/tf_static', self._on_tf_static, latched)
        n.create_subscription(MarkerArray, ns + 'markers', self._on_markers, latched)
        n.create_subscription(JointState, ns + 'joint_states', self._on_js, 10)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(n)
        # Tests destroy what they made on this node from their own thread. Destroyed while
        # this one waited in spin_once, an entity raised InvalidHandle there, and what that
        # spin had already taken was lost with it: an action goal's response once never came
        # (test_node_trajectory, in CI). Destroying waits for the spin to end (<= 50 ms).
        self.spin_lock = threading.Lock()
        n.sim_test_spin_lock = self.spin_lock  # for action_client's requests
        for name in ('destroy_subscription', 'destroy_publisher', 'destroy_client'):
            setattr(n, name, self._between_spins(getattr(n, name)))
        self._stop = False
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _between_spins(self, destroy):
        def call(entity):
            with self.spin_lock:
                return destroy(entity)
        return call

    def _spin(self):
        while not self._stop:
            try:
                with self.spin_lock:
                    self.executor.spin_once(timeout_sec=0.05)
            except Exception as exc:  # noqa: B902 (see below)
                # A subscription destroyed by the test's thread while this one waited on it
                # (robot_description's) raises here. Uncaught, it ended this thread: under load
                # every later case of a module then heard nothing and failed, one after another.
                with self.lock:
                    self.spin_errors.append(repr(exc))

    @staticmethod
    def _sec(t):
        return t.sec + t.nanosec * 1e-9

    def _on_clock(self, msg):
        with self.lock:
            self.clock.append(self._sec(msg.clock))
            self.heard['clock'] = time.monotonic()

    def _tf_entry(self, ts):
        tr, q = ts.transform.translation, ts.transform.rotation
        return (self._sec(ts.header.stamp), ts.header.frame_id, (tr.x, tr.y, tr.z),
                (q.x, q.y, q.z, q.w))

    def _on_tf(self, msg):
        with self.lock:
            self.heard['tf'] = time.monotonic()
            self.tf_stamps.append({self._sec(t.header.stamp) for t in msg.transforms})
            self._sends.extend((t.child_frame_id, self._sec(t.header.stamp))
                               for t in msg.transforms)
            for ts in msg.transforms:
                self.tf[ts.child_frame_id] = self._tf_entry(ts)

    @property
    def tf_sends(self) -> collections.Counter:
        """(child frame, stamp) -> times received, over the newest TF_SENDS_KEPT transforms."""
        return collections.Counter(self._sends)

    def _on_tf_static(self, msg):
        with self.lock:
            self.tf_static = {ts.child_frame_id: self._tf_entry(ts) for ts in msg.transforms}

    def _on_markers(self, msg):
        from visualization_msgs.msg import Marker
        with self.lock:
            for m in msg.markers:
                if m.action == Marker.DELETE:
                    self.markers.pop((m.ns, m.id), None)
                elif m.action == Marker.DELETEALL:
                    self.markers.clear()
                else:
                    self.markers[(m.ns, m.id)] = m

    def _on_js(self, msg):
        with self.lock:
            self.joint_states = msg
            self.heard['joint_states'] = time.monotonic()

    def report(self) -> str:
        """Say how long ago each topic was heard, and the newest times: for a failing wait."""
        with self.lock:
            now = time.monotonic()
            ages = ', '.join(f'{k} {now - t:.1f} s ago' for k, t in sorted(self.heard.items()))
            js = self.joint_states
            stamp = None if js is None else self._sec(js.header.stamp)
            return (f'heard: {ages or "nothing"}; spin errors {self.spin_errors[-3:]}; '
                    f'newest /clock '
                    f'{self.clock[-1] if self.clock else None}, joint_states stamp {stamp} with '
                    f'{0 if js is None else len(js.name)} joints')

    def latest_clock(self):
        with self.lock:
            return self.clock[-1] if self.clock else None

    def robot_description(self, entity: str, timeout: float = 15.0) -> str:
        """Subscribe late (transient local) and return the first description received."""
        from sim_node.ros.topics.descriptions import DESCRIPTION_QOS
        from std_msgs.msg import String
        got = []
        sub = self.node.create_subscription(String, f'/{entity}/robot_description',
                                            lambda msg: got.append(msg.data), DESCRIPTION_QOS)
        try:
            wait_for(lambda: got, timeout=timeout)
        finally:
            self.node.destroy_subscription(sub)
        return got[0]

    def links_without_frames(self, entity: str) -> list:
        """Links of an entity's robot_description with no frame on /tf or /tf_static."""
        from defusedxml import ElementTree
        links = [e.get('name') for e in ElementTree.fromstring(
            self.robot_description(entity)).findall('link')]

        def missing():
            with self.lock:
                frames = {**self.tf, **self.tf_static}
            return [link for link in links if f'{entity}/{link}' not in frames]
        try:  # a static frame may come a moment after the description
            wait_for(lambda: not missing(), timeout=5)
        except AssertionError:
            pass
        return missing()

    def close(self):
        self._stop = True
        self.thread.join(2)
        self.executor.shutdown()
        self.node.destroy_node()


@pytest.fixture
def watcher(rclpy_context):
    w = Watcher()
    yield w
    w.close()


@pytest.fixture(scope='module')
def display():
    """Start a virtual X screen (Xvfb) for a module's windows; skip where xvfb is missing."""
    from sim_node.view.xvfb import VirtualDisplay
    if not VirtualDisplay.available():
        pytest.skip("needs a virtual display: Debian's xvfb (sudo apt-get install xvfb, or "
                    'make setup as root)')
    with VirtualDisplay() as d:
        yield d
