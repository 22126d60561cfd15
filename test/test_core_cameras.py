"""
Cameras, laser scans and sensors of the core, with MuJoCo's real offscreen renderer.

Geometry is checked against theory: a ball at a known place shows at the pixel the pinhole
model of camera_info predicts, at the depth its distance along the optical axis gives.
"""

import math
import os
from pathlib import Path
import subprocess
import sys

from msg_adapters import perception as pm
import numpy as np
import pytest
from sim_node.core.base import quat
from sim_node.core.cameras import CameraRig
from sim_node.core.lidar import LaserConfig, LaserScanner
from sim_node.core.models import sources
from sim_node.core.world import World

ROOT = Path(__file__).resolve().parent.parent

# A camera 2 m from the origin, looking at it from the side and above (xyaxes: its x and y
# axes in the world; it looks down its -z); a red ball at a known place in view.
EYE = np.array([1.2, -1.4, 1.1])
BALL = np.array([0.15, 0.1, 0.2])
BALL_R = 0.06


def _look_at(eye, target):
    f = target - eye
    f = f / np.linalg.norm(f)
    x = np.cross(f, [0, 0, 1.0])
    x /= np.linalg.norm(x)
    return x, np.cross(x, f)


X_AXIS, Y_AXIS = _look_at(EYE, np.zeros(3))
# The ball glows (emission, no specular light): evenly red, so its pixels' centroid is where its
# centre projects, not biased towards its lit side.
SCENE = f"""<mujoco><compiler angle="radian"/>
<asset><material name="glow" rgba="1 0 0 1" emission="1" specular="0"/>
  <texture type="skybox" builtin="gradient" rgb1="1 1 1" rgb2="0 0 0" width="32" height="32"/>
</asset><worldbody>
  <light pos="0 0 3" dir="0 0 -1" directional="true"/>
  <camera name="side" pos="{' '.join(map(str, EYE))}" LENS
          xyaxes="{' '.join(map(str, X_AXIS))} {' '.join(map(str, Y_AXIS))}"/>
  <body name="ball" pos="{' '.join(map(str, BALL))}">
    <geom type="sphere" size="{BALL_R}" material="glow"/></body>
</worldbody></mujoco>"""
FOVY = 'fovy="55"'
# A camera given as a sensor (MuJoCo's intrinsics): an off-centre principal point, non-square
# pixels at 320 x 240 (sensor aspect 1.2, image aspect 1.33).
SENSOR = ('sensorsize="0.006 0.005" focal="0.006 0.0058" principal="0.0004 -0.0003" '
          'resolution="320 240"')


def _red_centroid(rgb):
    red = (rgb[..., 0] > 120) & (rgb[..., 1] < 60) & (rgb[..., 2] < 60)
    ys, xs = np.nonzero(red)
    assert len(xs) > 20, 'the ball is not in the picture'
    return xs.mean(), ys.mean()


def _project(point, pos, q_wxyz, k):
    """World point -> (u, v, z) through an optical frame at (pos, q) and camera matrix K."""
    p = quat.rotate(quat.conj(np.asarray(q_wxyz)), np.asarray(point) - pos)
    fx, cx, fy, cy = k[0], k[2], k[4], k[5]
    return fx * p[0] / p[2] + cx, fy * p[1] / p[2] + cy, p[2]


@pytest.mark.parametrize('lens, width, height', [(FOVY, 320, 240), (FOVY, 160, 200),
                                                 (SENSOR, 320, 240)])
def test_a_ball_shows_where_camera_info_and_the_optical_frame_predict(lens, width, height):
    world = World.from_string(SCENE.replace('LENS', lens))
    rig = CameraRig(world, width, height)
    (frame,) = rig.capture()
    info = world.model_info
    k = pm.camera_info(frame.intrinsics, width, height, frame.time, 'side_optical_frame').k
    # The optical frame as /tf_static gives it (the camera sits on the world body).
    (tf,) = pm.device_transforms(info, 0.0, ['world'], info.cameras, [], [])
    r = tf.transform.rotation
    q = np.array([r.w, r.x, r.y, r.z])
    pos = np.array([tf.transform.translation.x, tf.transform.translation.y,
                    tf.transform.translation.z])
    assert tf.child_frame_id == 'side_optical_frame' and tf.header.frame_id == 'world'
    np.testing.assert_allclose(pos, EYE)
    u, v, z = _project(BALL, pos, q, k)
    cu, cv = _red_centroid(frame.rgb)
    # Within a third of a pixel: half a pixel off is the classic principal point mistake.
    assert abs(cu - u) < 0.3 and abs(cv - v) < 0.3, ((cu, cv), (u, v))
    # Depth along the optical axis of the ball's surface on the ray through its centre.
    dist = np.linalg.norm(BALL - EYE)
    expected = z * (dist - BALL_R) / dist
    got = frame.depth[int(round(v)), int(round(u))]
    assert got == pytest.approx(expected, abs=0.005)
    assert np.isinf(frame.depth[0, 0]) and frame.depth[0, 0] > 0  # sky (skybox): nothing hit
    assert frame.time == world.time


def test_points_from_depth_put_the_ball_where_it_is():
    world = World.from_string(SCENE.replace('LENS', FOVY))
    (frame,) = CameraRig(world, 160, 120).capture()
    msg = pm.points(frame.depth, frame.rgb, frame.intrinsics, frame.time, 'side_optical_frame')
    assert (msg.height, msg.width, msg.point_step) == (120, 160, 16)
    cloud = np.frombuffer(bytes(msg.data), '<f4').reshape(120, 160, 4)
    rgb = cloud[..., 3].copy().view(np.uint32)
    red = (rgb >> 16 & 255) > 120
    red &= ((rgb >> 8 & 255) < 60) & np.isfinite(cloud[..., 2])
    # Inside the silhouette only: edge pixels blend ball and background (multisampling).
    inner = red.copy()
    inner[1:-1, 1:-1] &= red[:-2, 1:-1] & red[2:, 1:-1] & red[1:-1, :-2] & red[1:-1, 2:]
    pts = cloud[inner][:, :3].astype(float)
    assert len(pts) > 10
    # The red points lie on the ball's surface, in the world: typically within 2 mm, each
    # within a pixel's footprint (17 mm here) where the surface turns away.
    world_pts = frame.pos + np.array([quat.rotate(frame.quat_wxyz, p) for p in pts])
    off = np.abs(np.linalg.norm(world_pts - BALL, axis=1) - BALL_R)
    assert np.median(off) < 0.002 and off.max() < 0.01, off
    assert np.isnan(cloud[0, 0, :3]).all()  # sky: no point


def test_optical_frame_is_z_forward_x_right_y_down():
    world = World.from_string(SCENE.replace('LENS', FOVY))
    (frame,) = CameraRig(world, 64, 48).capture()
    fwd = quat.rotate(frame.quat_wxyz, np.array([0.0, 0, 1]))
    right = quat.rotate(frame.quat_wxyz, np.array([1.0, 0, 0]))
    down = quat.rotate(frame.quat_wxyz, np.array([0.0, 1, 0]))
    np.testing.assert_allclose(fwd, -EYE / np.linalg.norm(EYE), atol=1e-9)  # at the origin
    np.testing.assert_allclose(right, X_AXIS, atol=1e-9)
    np.testing.assert_allclose(down, -Y_AXIS, atol=1e-9)


TRACKING = """<mujoco><worldbody>
  <camera name="follow" pos="0 -2 1" mode="targetbody" target="ball"/>
  <body name="ball" pos="0 0 0.5"><freejoint/><geom type="sphere" size="0.05"/></body>
</worldbody><option gravity="0 0 0"/></mujoco>"""


def test_a_tracking_camera_keeps_its_target_on_the_optical_axis():
    world = World.from_string(TRACKING)
    info = world.model_info
    assert not info.cameras[0].fixed
    # Not a fixed frame: no /tf_static entry (the node sends it on /tf with each image).
    assert pm.device_transforms(info, 0.0, ['world', 'ball'], info.cameras, [], []) == []
    rig = CameraRig(world, 64, 48)
    for target in ([0.0, 0.0, 0.5], [1.0, 0.5, 1.5]):
        world.set_entity_state('ball', position=target)
        (frame,) = rig.capture()
        axis = quat.rotate(frame.quat_wxyz, np.array([0.0, 0, 1]))
        to_ball = np.array(target) - frame.pos
        np.testing.assert_allclose(axis, to_ball / np.linalg.norm(to_ball), atol=1e-6)
        np.testing.assert_allclose(frame.pos, [0, -2, 1])
    tf = pm.moving_camera_tf('follow_optical_frame', 'world', frame.pos, frame.quat_wxyz,
                             frame.time)
    assert tf.transforms[0].header.frame_id == 'world'


DRONE = """<mujoco><worldbody><body name="drone" pos="0 0 10">
  <freejoint/><geom type="box" size="0.1 0.1 0.1"/>
  <camera name="belly" pos="0 0 -0.2"/></body></worldbody></mujoco>"""


def test_a_camera_on_a_falling_body_is_where_its_body_is_at_the_image_time():
    world = World.from_string(DRONE)
    world.step(500)  # 1 s of free fall: 9.8 m/s, 2 cm a step
    (frame,) = CameraRig(world, 32, 24).capture()
    state = world.get_entity_state('drone')
    assert frame.time == state.time
    np.testing.assert_allclose(frame.pos, state.position + [0, 0, -0.2], atol=1e-9)


def test_cameras_do_not_see_sites():
    world = World.from_string('<mujoco><worldbody><camera name="c" pos="0 0 2"/>'
                              '<site name="marker" size="0.5" rgba="1 0 0 1"/>'
                              '</worldbody></mujoco>')
    (frame,) = CameraRig(world, 32, 24).capture()
    assert np.all(np.isinf(frame.depth)) and frame.rgb.max() == 0


def test_intrinsics_from_fovy():
    world = World.from_string('<mujoco><worldbody><camera name="c" fovy="90"/></worldbody>'
                              '</mujoco>')
    (frame,) = CameraRig(world, 640, 480).capture()
    fx, fy, cx, cy = frame.intrinsics
    assert fx == pytest.approx(240.0) and fy == pytest.approx(240.0)  # square pixels
    assert (cx, cy) == pytest.approx((319.5, 239.5))


def test_a_world_without_cameras_starts_no_renderer():
    world = World.from_string('<mujoco><worldbody><geom type="plane" size="1 1 .1"/>'
                              '</worldbody></mujoco>')
    rig = CameraRig(world)
    assert rig.capture() == [] and rig.cameras() == ()
    assert not rig.renderer_started


CAMERA_BOT = """<mujoco><worldbody><body name="head">
  <geom type="box" size="0.05 0.05 0.05" rgba="0 0 1 1"/>
  <camera name="eye" pos="0 0 -0.06" fovy="60"/></body></worldbody></mujoco>"""


def test_a_spawned_camera_appears_and_disappears_with_its_entity():
    world = World.from_string(SCENE.replace('LENS', FOVY))
    rig = CameraRig(world, 64, 48)
    assert [f.camera.name for f in rig.capture()] == ['side']
    world.spawn('bot', sources.from_model_text(CAMERA_BOT), position=[0.0, 0.0, 1.0])
    frames = rig.capture()
    assert [f.camera.name for f in frames] == ['side', 'bot/eye']
    # It looks straight down from 0.94 m (under its head) at the ball: the nearest point is
    # the ball's top.
    assert np.nanmin(frames[1].depth) == pytest.approx(0.94 - BALL[2] - BALL_R, abs=0.005)
    world.delete('bot')
    assert [f.camera.name for f in rig.capture()] == ['side']


#: A textured tetrahedron: a mesh, a texture and a material the scene's context lacks.
TETRA = """<mujoco><asset><mesh name="tet" vertex="0 0 0  .3 0 0  0 .3 0  0 0 .3"/>
  <texture name="chk" type="2d" builtin="checker" rgb1="0 1 0" rgb2="0 0 1" width="8"
           height="8"/><material name="chk" texture="chk"/></asset>
  <worldbody><body name="t"><geom type="mesh" mesh="tet" material="chk"/></body></worldbody>
</mujoco>"""


@pytest.mark.parametrize('floor', ['2 2 0.1', '0 0 1'], ids=['finite', 'infinite'])
def test_frames_after_edits_are_those_of_a_camera_started_afresh(floor):
    """
    Each frame after spawns and deletes is, pixel for pixel, what a new renderer draws.

    A spawn of primitives keeps the OpenGL context (making one holds every thread for ~75 ms);
    one that brings a mesh and a texture gets a new one. Compared: the floor's grid (an
    infinite plane's follows the world's extent) and the ball's shadow on it (clipped by the
    extent).
    """
    world = World.from_string(SCENE.replace('LENS', FOVY).replace(
        '<worldbody>', f'<worldbody><geom type="plane" size="{floor}" rgba=".6 .6 .6 1"/>'))
    rig = CameraRig(world, 96, 72)
    rig.capture()
    made = rig.contexts_made

    def same_as_fresh():
        fresh = CameraRig(world, 96, 72).capture()[0]
        frame = rig.capture()[0]
        return np.array_equal(frame.rgb, fresh.rgb) and np.array_equal(frame.depth, fresh.depth)

    world.spawn('crate', sources.primitive('box', [0.05] * 3), position=[-0.1, -0.1, 0.05])
    assert same_as_fresh()
    if floor != '0 0 1':
        assert rig.contexts_made == made  # kept: nothing it holds changed
    world.spawn('far', sources.primitive('sphere', [0.1]), position=[40.0, 0.0, 0.1])
    assert same_as_fresh()  # a larger world
    if floor == '0 0 1':
        assert rig.contexts_made > made  # an infinite floor's grid: made again
    made = rig.contexts_made
    world.spawn('tetra', sources.from_model_text(TETRA), position=[0.0, -0.3, 0.0])
    assert same_as_fresh()
    assert rig.contexts_made > made  # a new mesh and texture: made again
    world.delete('crate')
    assert same_as_fresh()


def test_camera_selection_by_pattern_and_depth_off():
    world = World.from_string(SCENE.replace('LENS', FOVY))
    world.spawn('bot', sources.from_model_text(CAMERA_BOT), position=[0.0, 0.0, 1.0])
    frames = CameraRig(world, 32, 24, patterns=['bot/*'], depth=False).capture()
    assert [f.camera.name for f in frames] == ['bot/eye'] and frames[0].depth is None
    assert CameraRig(world, 32, 24, patterns=['none']).capture() == []


# --------------------------------------------------------------------------- laser scans

LIDAR_SCENE = """<mujoco><compiler angle="radian"/><worldbody>
  <body name="bot" pos="0 0 0.5" euler="0 0 1.5707963267948966">
    <geom type="cylinder" size="0.2 0.1"/>
    <site name="lidar" pos="0 0 0"/>
  </body>
  <body name="wall" pos="2 0 0.5"><geom type="box" size="0.05 3 0.5"/></body>
  <body name="post" pos="0 0.1 0.5"><geom type="box" size="0.01 0.01 0.5"/></body>
</worldbody></mujoco>"""


def test_a_laser_scan_sees_a_wall_at_its_distance_and_not_its_own_body():
    world = World.from_string(LIDAR_SCENE)
    cfg = LaserConfig(angle_min=-math.pi, angle_max=math.pi, samples=721,
                      range_min=0.15, range_max=5.0)
    (reading,) = LaserScanner(world, cfg).scan(['lidar'])
    angles = cfg.angles()
    # The body faces +y (a quarter turn): the wall, 1.95 m away along world +x, is at -90 deg
    # in the scanner's frame, and each ray meets it at 1.95 / cos(angle from the normal).
    off = angles + math.pi / 2
    facing = np.abs(off) < 0.9  # within the wall's 3 m half length
    np.testing.assert_allclose(reading.ranges[facing], 1.95 / np.cos(off[facing]), rtol=1e-6)
    # Its own cylinder (radius 0.2) is never seen; a post 0.1 m away inside it is closer than
    # range_min (-inf); the half plane away from the wall sees nothing (+inf).
    assert not np.any((reading.ranges > 0) & (reading.ranges < 0.25))
    assert reading.ranges[np.argmin(np.abs(angles - 0.0))] == -np.inf
    behind = np.abs(angles - math.pi / 2) < 1.0
    assert np.all(np.isposinf(reading.ranges[behind]))
    assert reading.time == world.time


def test_a_laser_scan_of_a_missing_site_is_skipped_and_bad_settings_are_refused():
    world = World.from_string(LIDAR_SCENE)
    assert LaserScanner(world).scan(['nope']) == []
    from sim_node.core.errors import InvalidArgumentError
    with pytest.raises(InvalidArgumentError, match='laser scan settings'):
        LaserConfig(range_min=2.0, range_max=1.0)
    with pytest.raises(InvalidArgumentError):
        LaserConfig(samples=0)


# --------------------------------------------------------------------------- sensors

SENSOR_SCENE = """<mujoco><option gravity="0 0 -9.81"/><worldbody>
  <geom type="plane" size="2 2 .1"/>
  <body name="puck" pos="0 0 0.05"><freejoint/>
    <geom type="box" size="0.05 0.05 0.05" mass="1"/>
    <site name="imu"/><site name="ft" pos="0 0 0.05"/>
    <site name="down" pos="0 0 -0.049" euler="180 0 0"/>
    <site name="sole" type="box" pos="0 0 -0.05" size="0.06 0.06 0.01"/>
  </body></worldbody>
  <sensor>
    <framequat objtype="site" objname="imu"/><gyro site="imu"/>
    <accelerometer site="imu"/>
    <force site="ft"/><torque site="ft"/>
    <rangefinder name="floor_range" site="down"/>
    <touch name="contact" site="sole"/>
  </sensor></mujoco>"""


def test_sensors_are_grouped_as_ros_messages_and_read_as_physics_says():
    world = World.from_string(SENSOR_SCENE)
    world.step(500)
    snap = world.snapshot()
    kinds = {(s.kind, s.name) for s in snap.info.sensors}
    assert kinds == {('imu', 'imu'), ('wrench', 'ft'), ('range', 'floor_range'),
                     ('generic', 'contact')}
    by = {s.kind: s for s in snap.info.sensors}
    imu = pm.imu(by['imu'], snap.sensordata, snap.time, 'puck/imu')
    # At rest an accelerometer reads the reaction to gravity, +g up; no rotation.
    assert imu.linear_acceleration.z == pytest.approx(9.81, abs=1e-3)
    assert abs(imu.angular_velocity.x) < 1e-6 and imu.orientation.w == pytest.approx(1.0)
    assert imu.orientation_covariance[0] == 0.0  # present
    rng = pm.range_reading(by['range'], snap.sensordata, snap.time, 'puck/floor_range')
    assert rng.range == pytest.approx(0.001, abs=2e-3)  # 1 mm above the floor it rests on
    touch = pm.generic(by['generic'], snap.sensordata)
    assert touch.layout.dim[0].label == 'touch'
    assert touch.data[0] == pytest.approx(9.81, rel=0.02)  # it carries the puck's weight
    assert imu.header.stamp.sec + imu.header.stamp.nanosec * 1e-9 == pytest.approx(snap.time)


def test_a_rangefinder_that_sees_nothing_reads_plus_inf_and_its_frame_looks_along_x():
    world = World.from_string(SENSOR_SCENE.replace('euler="180 0 0"', ''))  # looks up
    snap = world.snapshot()
    (spec,) = [s for s in snap.info.sensors if s.kind == 'range']
    assert math.isinf(pm.range_reading(spec, snap.sensordata, 0.0, 'f').range)
    info = snap.info
    frames = ['world', 'puck']
    (tf,) = pm.device_transforms(info, 0.0, frames, [], [], [spec])
    r = tf.transform.rotation
    x_axis = quat.rotate(np.array([r.w, r.x, r.y, r.z]), np.array([1.0, 0, 0]))
    np.testing.assert_allclose(x_axis, [0, 0, 1], atol=1e-12)  # the site's z: the ray
    assert tf.child_frame_id == 'puck/floor_range' and tf.header.frame_id == 'puck'


# --------------------------------------------------------------------------- pictures, backend

def _python(code: str, env: dict = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-c', code], cwd=ROOT, capture_output=True,
                          text=True, env=dict(os.environ, **(env or {})), timeout=120)


def test_snapshot_writes_a_png_of_the_default_scene(tmp_path):
    from PIL import Image
    out = tmp_path / 'scene.png'
    done = subprocess.run([sys.executable, '-m', 'sim_node.snapshot', 'default', '-o', str(out),
                           '--width', '200', '--height', '150'], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    img = np.asarray(Image.open(out))
    assert img.shape == (150, 200, 3)
    assert img.reshape(-1, 3).std(axis=0).min() > 10  # a picture, not a blank
    bad = subprocess.run([sys.executable, '-m', 'sim_node.snapshot', 'default', '--camera',
                          'nope', '-o', str(tmp_path / 'x.png')], cwd=ROOT, capture_output=True,
                         text=True, timeout=120)
    assert bad.returncode == 1 and "no camera named 'nope'" in bad.stderr
    assert 'overview' in bad.stderr


def test_a_missing_gl_backend_says_what_to_install():
    code = ('import ctypes.util; ctypes.util.find_library = lambda name: None\n'
            'from sim_node.core.devices.rendering import Renderer, RenderingUnavailableError\n'
            'try:\n    Renderer(8, 8)\nexcept RenderingUnavailableError as e:\n    print(e)')
    out = _python(code, {'MUJOCO_GL': ''})
    assert 'apt-get install libegl1' in out.stdout and 'libosmesa6' in out.stdout, out.stderr
    out = _python(code, {'MUJOCO_GL': 'glx'})
    assert "MUJOCO_GL='glx' cannot render headless" in out.stdout, out.stderr


@pytest.mark.parametrize('grow', [False, True], ids=['same size', 'a larger camera'])
def test_uploading_a_spawned_meshs_graphics_lets_every_other_thread_run(tmp_path, grow):
    """
    A new mesh's upload to the renderer holds no other thread up: the stepping loop steps on.

    MuJoCo's bindings hold the GIL while they make an OpenGL context (they upload every mesh
    and texture): at each spawn of a robot with meshes every thread stood still (/clock 100 to
    290 ms, issue 52, item 1), and again when a robot's larger camera made a new renderer.
    A thread ticking every millisecond is never held up longer than 50 ms while the rig
    uploads a 200,000-face mesh and a 2048 x 2048 texture.
    """
    from conftest import Ticker
    import trimesh
    sphere = trimesh.creation.icosphere(subdivisions=8, radius=0.2)
    mesh = trimesh.Trimesh(sphere.vertices, sphere.faces[:200_000], process=False)
    (tmp_path / 'dome.stl').write_bytes(mesh.export(file_type='stl'))
    world = World.from_string(SCENE.replace('LENS', FOVY))
    rig = CameraRig(world, 64, 48)
    rig.capture()
    dome = (f'<mujoco><asset><mesh name="dome" file="{tmp_path / "dome.stl"}"/>'
            '<texture name="big" type="2d" builtin="checker" width="2048" height="2048" '
            'rgb1="1 0 0" rgb2="0 1 0"/><material name="big" texture="big"/></asset>'
            '<worldbody><body name="d"><geom type="mesh" mesh="dome" material="big"/></body>'
            '</worldbody></mujoco>')
    world.spawn('dome', sources.from_model_text(dome, str(tmp_path)), position=[0.0, 0.0, 0.5])
    with Ticker() as ticker:
        frames = rig.capture(sizes={'side': (128, 96)} if grow else None)
    held, spent = ticker.held, ticker.spent
    assert spent > 0.1  # the upload is long enough to matter
    assert held < 0.05, f'held up {held * 1000:.0f} ms of a {spent * 1000:.0f} ms capture'
    assert frames[0].rgb.shape == ((96, 128, 3) if grow else (48, 64, 3))
    assert (frames[0].rgb != frames[0].rgb[0, 0]).any()  # drawn


def test_the_processs_first_camera_lets_every_other_thread_run():
    """
    A node's first camera holds no other thread up while its GL context is made.

    The bindings hold the GIL while they make a context; the process's first was made by
    them (to raise what MuJoCo finds wrong) and held every thread of a starting node (the
    stepping loop, /clock, the services) 262 ms for the default scene's 640-pixel camera, and
    490 ms at 2048. A fresh process (the first context is once per process) with a thread
    ticking every millisecond while a 2048-pixel renderer takes the default scene: held up for
    less than a quarter of the time the context takes (with the bindings it was held all of
    it, 766 of 765 ms; with the probe about 10 of 700 ms). A ratio, not a wall-clock bound, so
    that a busy machine, which slows the ticks and the context alike, does not decide it; the
    figures are in docs/benchmarks.md. (Starting the GL backend, before, loads its libraries
    once per process, with the GIL held by the loader: 30 to 80 ms here.)
    """
    code = '\n'.join([
        'import sys, time; sys.path.insert(0, "test")',
        'import mujoco',
        'from conftest import Ticker',
        'from sim_node.core.devices.rendering import Renderer',
        'model = mujoco.MjModel.from_xml_path("scenes/default.xml")',
        'renderer = Renderer(2048, 2048)',
        'with Ticker() as ticker:',
        '    renderer.use_model(model)',
        'renderer.close()',
        'print(ticker.held, ticker.spent)'])
    out = _python(code)
    assert out.returncode == 0, out.stderr
    held, spent = map(float, out.stdout.split()[-2:])
    assert spent > 0.1  # the context is long enough to matter
    assert held < spent / 4, f'held up {held * 1000:.0f} ms of {spent * 1000:.0f} ms'


def test_a_capture_holds_the_world_lock_for_one_copy_of_the_data():
    # Under a storm of requests each MuJoCo call gives the GIL away and waits for it back: a
    # capture that brought poses up to date and filled its scenes under the world lock held
    # the stepping loop off for up to 157 ms. What it calls under the lock is watched here.
    world = World.from_string(DRONE)
    rig = CameraRig(world, 32, 24)
    under_lock, seen = [], []

    def watch(frame, event, func):
        if event == 'c_call' and getattr(func, '__module__', '') == 'mujoco._functions':
            seen.append(func.__name__)
            if world.holds_lock():
                under_lock.append(func.__name__)

    world.step(500)  # falling 2 cm a step: a pose a step behind would show
    sys.setprofile(watch)
    try:
        (frame,) = rig.capture()
    finally:
        sys.setprofile(None)
    assert 'mjv_updateScene' in seen  # the watch sees MuJoCo's calls
    assert under_lock == ['mj_copyData']
    state = world.get_entity_state('drone')  # drawn from the copy: the state now
    assert frame.time == state.time
    np.testing.assert_allclose(frame.pos, state.position + [0, 0, -0.2], atol=1e-9)
