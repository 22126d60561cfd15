"""
SDF worlds and models in the core (issue 54): what Gazebo would make of them.

Checked against theory and hand-computed poses, not against the reader's own code.

Every SDF here is written for the test (the corpus of others' files is test_core_sdf_corpus).
"""

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from sim_node.core.base.config import WorldConfig
from sim_node.core.errors import ResourceParseError, UnsupportedElementsError
from sim_node.core.models import sdf_elements, sdf_files, sources, world_sources
from sim_node.core.world import World

G = 9.81


def sdf(body: str, version: str = '1.9', physics: str = '') -> str:
    return (f'<?xml version="1.0"?><sdf version="{version}"><world name="w">'
            f'<physics name="p" type="ignored"><max_step_size>0.001</max_step_size>'
            f'{physics}</physics><gravity>0 0 -{G}</gravity>{body}</world></sdf>')


def box_link(name: str, size: str = '0.1 0.1 0.1', mass: float = 1.0, pose: str = '',
             extra: str = '', collide: bool = True) -> str:
    i = mass * 0.1 ** 2 / 6
    geometry = f'<geometry><box><size>{size}</size></box></geometry>'
    part = f'<collision name="c">{geometry}{extra}</collision>' if collide else ''
    return (f'<link name="{name}">{pose}<inertial><mass>{mass}</mass><inertia><ixx>{i}</ixx>'
            f'<iyy>{i}</iyy><izz>{i}</izz></inertia></inertial>{part}'
            f'<visual name="v">{geometry}</visual></link>')


def at(values: str, relative_to: str = '') -> str:
    """Return a <pose> element: `values` relative to `relative_to` ('' : the default)."""
    rel = f' relative_to="{relative_to}"' if relative_to else ''
    return f'<pose{rel}>{values}</pose>'


def load(text: str, folder=None, config: WorldConfig = WorldConfig(), **places) -> World:
    """Make the world of SDF text as load_world does (World.from_file for files)."""
    plan = world_sources.world_source(text, str(folder) if folder else None,
                                      places=sdf_files.Places.of(**places))
    return World.from_plan(plan, config, 'test')


def pos(world: World, body: str) -> np.ndarray:
    return np.array(world.read(lambda m, d: d.xpos[m.body(body).id].copy()))


def forward(world: World) -> None:
    world.step(1)


# ------------------------------------------------------------------ the world's settings

def test_a_worlds_physics_gravity_field_scene_and_lights_are_read():
    w = load(sdf('<magnetic_field>6e-06 2.3e-05 -4.2e-05</magnetic_field>'
                 '<scene><ambient>0.3 0.2 0.1 1</ambient><background>0.1 0.2 0.3 1</background>'
                 '</scene><light type="directional" name="sun"><pose>0 0 10 0 0 0</pose>'
                 '<direction>0 0 -1</direction></light>'
                 '<light type="spot" name="lamp"><pose>1 2 3 0 0 0</pose>'
                 '<spot><outer_angle>0.5</outer_angle></spot></light>',
                 physics='<real_time_factor>0.5</real_time_factor><ode><solver><iters>70'
                         '</iters></solver></ode>'))
    opt = w.read(lambda m, d: (m.opt.timestep, m.opt.gravity.copy(), m.opt.magnetic.copy(),
                               m.opt.iterations, m.nlight, m.vis.headlight.ambient.copy(),
                               m.light_pos[1].copy()))
    assert opt[0] == 0.001 and np.allclose(opt[1], [0, 0, -G])
    assert np.allclose(opt[2], [6e-6, 2.3e-5, -4.2e-5]) and opt[3] == 70
    assert opt[4] == 2 and np.allclose(opt[5], [0.3, 0.2, 0.1]) and np.allclose(opt[6], [1, 2, 3])
    assert w.real_time_factor == 0.5 and w.name == 'w'
    plan = world_sources.world_source(sdf('<scene><background>0.1 0.2 0.3 1</background>'
                                          '</scene>'))
    sky = [t for t in plan.spec.textures if t.type == mujoco.mjtTexture.mjTEXTURE_SKYBOX]
    assert np.allclose(sky[0].rgb1, [0.1, 0.2, 0.3])  # the background is the sky's colour


def test_a_world_file_loads_through_a_session_paced_by_its_own_factor(tmp_path):
    import time
    from sim_node.session import Session
    path = tmp_path / 'slow.world'  # Gazebo classic's suffix
    path.write_text(sdf(pendulum(), physics='<real_time_factor>0.5</real_time_factor>'))
    with Session() as session:
        loaded = session.load_file(str(path))
        assert loaded.name == 'w' and loaded.loop.real_time_factor == 0.5
        t0, wall = loaded.world.time, time.monotonic()
        time.sleep(1.0)
        assert loaded.world.time - t0 <= 0.5 * (time.monotonic() - wall) + 0.05
        # a configuration of the caller's own wins, unless it asks for the file's pace
        assert session.load_file(str(path), WorldConfig(real_time_factor=0.0)) \
            .loop.real_time_factor == 0.0
        assert session.load_file(str(path), WorldConfig(real_time_factor=0.0),
                                 paced_by_file=True).loop.real_time_factor == 0.5


def test_gravity_inside_physics_is_read_before_sdf_1_6():
    text = sdf('', version='1.5', physics='<gravity>0 0 -3</gravity>').replace(
        f'<gravity>0 0 -{G}</gravity>', '')
    assert load(text).read(lambda m, d: m.opt.gravity[2]) == -3


def test_a_free_model_falls_as_gravity_says_and_a_static_one_stays():
    w = load(sdf(f'<model name="ball"><pose>0 0 10 0 0 0</pose>{box_link("b")}</model>'
                 f'<model name="shelf"><static>true</static><pose>3 0 2 0 0 0</pose>'
                 f'{box_link("s")}</model>'))
    w.step(500)  # 0.5 s
    t, dt = w.time, w.timestep
    # MuJoCo's integrator (velocity first, then position) gives z0 - g t (t + dt) / 2 exactly
    assert w.get_entity_state('ball').position[2] == pytest.approx(10 - G * t * (t + dt) / 2,
                                                                   abs=1e-9)
    assert np.allclose(w.get_entity_state('shelf').position, [3, 0, 2])
    cats = {e.name: e.category for e in w.entities()}
    assert cats == {'ball': 'dynamic', 'shelf': 'static'}


# ------------------------------------------------------------------ poses and frames

def test_poses_follow_relative_to_frames_nested_models_and_placement_frames():
    """Each link's world position, by hand: translations and turns of 90 degrees."""
    half = math.pi / 2
    w = load(sdf(
        f'<model name="m"><static>true</static><pose>1 0 0 0 0 {half}</pose>'
        f'<frame name="f"><pose>0 2 0 0 0 0</pose></frame>'
        + box_link('a', pose=at('1 0 0 0 0 0', 'f'))
        + box_link('b', pose=at('0 0 3 0 0 0', 'a'))
        + '<model name="inner"><pose relative_to="b">1 0 0 0 0 0</pose>'
        + box_link('c', pose=at('0 1 0 0 0 0')) + '</model>'
        '</model>'
        '<model name="placed" placement_frame="tip"><static>true</static>'
        '<pose>5 5 5 0 0 0</pose><frame name="tip"><pose>0 0 1 0 0 0</pose></frame>'
        + box_link('p') + '</model>'
        '<model name="deg"><static>true</static><pose degrees="true">0 0 0 0 0 90</pose>'
        + box_link('d', pose=at('1 0 0 0 0 0')) + '</model>'
        '<model name="q"><static>true</static><pose rotation_format="quat_xyzw">'
        '0 0 0 0 0 0.7071068 0.7071068</pose>' + box_link('e', pose=at('1 0 0 0 0 0'))
        + '</model>'))
    forward(w)
    # model m is at (1,0,0) turned +90 deg about z: its x is the world's y, its y the world's -x
    assert np.allclose(pos(w, 'm'), [1 - 2, 1, 0], atol=1e-9)  # link a: f + (1,0,0)
    assert np.allclose(pos(w, 'm/b'), [-1, 1, 3], atol=1e-9)
    assert np.allclose(pos(w, 'm/inner/c'), [-1 - 1, 1 + 1, 3], atol=1e-9)
    assert np.allclose(pos(w, 'placed'), [5, 5, 4], atol=1e-9)  # its tip is where it is put
    assert np.allclose(pos(w, 'deg'), [0, 1, 0], atol=1e-6)
    assert np.allclose(pos(w, 'q'), [0, 1, 0], atol=1e-6)


@pytest.mark.parametrize('version, expect_y', [('1.4', True), ('1.6', False), ('1.9', False)])
def test_a_joint_axis_is_in_the_joint_frame_except_in_sdf_1_4(version, expect_y):
    """A joint frame turned 90 deg about z: its axis x is the world's y (1.4: the model's x)."""
    w = load(sdf(f'<model name="r"><pose>0 0 1 0 0 0</pose>{box_link("base")}'
                 + box_link('arm', pose=at('0 0 -0.5 0 0 0')) +
                 '<joint name="fix" type="fixed"><parent>world</parent><child>base</child>'
                 '</joint><joint name="j" type="revolute"><pose>0 0 0 0 0 1.5707963268</pose>'
                 '<parent>base</parent><child>arm</child><axis><xyz>1 0 0</xyz></axis>'
                 '</joint></model>', version=version))
    forward(w)
    axis = w.read(lambda m, d: d.xaxis[m.joint('r/j').id].copy())
    assert np.allclose(axis, [1, 0, 0] if expect_y else [0, 1, 0], atol=1e-6)


def test_expressed_in_names_the_frame_of_an_axis():
    w = load(sdf(f'<model name="r">{box_link("base")}{box_link("arm")}'
                 f'<joint name="fix" type="fixed"><parent>world</parent><child>base</child>'
                 f'</joint><joint name="j" type="revolute"><pose>0 0 0 0 0 1.5707963268</pose>'
                 f'<parent>base</parent><child>arm</child><axis>'
                 f'<xyz expressed_in="__model__">1 0 0</xyz></axis></joint></model>'))
    forward(w)
    assert np.allclose(w.read(lambda m, d: d.xaxis[m.joint('r/j').id].copy()), [1, 0, 0],
                       atol=1e-6)


# ------------------------------------------------------------------ joints against theory

def pendulum(kind: str = 'revolute', axis: str = '<axis><xyz>1 0 0</xyz></axis>',
             mass: float = 2.0, length: float = 1.0, extra: str = '') -> str:
    """Return a model: a point-like bob `length` below a hinge 3 m up, its base welded."""
    bob = (f'<link name="bob"><pose>0 0 {3 - length} 0 0 0</pose><inertial><mass>{mass}'
           f'</mass><inertia><ixx>1e-6</ixx><iyy>1e-6</iyy><izz>1e-6</izz></inertia>'
           f'</inertial></link>')
    return ('<model name="p">' + box_link('base', pose=at('0 0 3 0 0 0'), collide=False) +
            f'{bob}<joint name="fix" type="fixed"><parent>world</parent><child>base</child>'
            f'</joint><joint name="hinge" type="{kind}"><pose>0 0 {length} 0 0 0</pose>'
            f'<parent>base</parent><child>bob</child>{axis}{extra}</joint></model>')


def period(world: World, joint: str, seconds: float = 6.0) -> float:
    """Return the mean period of a joint's swing from its upward zero crossings."""
    crossings, last = [], None
    while world.time < seconds:
        world.step(1)
        q = world.get_joint_states()[joint][0]
        if last is not None and last < 0 <= q:
            crossings.append(world.time)
        last = q
    return float(np.mean(np.diff(crossings)))


def test_a_revolute_pendulum_swings_at_its_theoretical_period():
    w = load(sdf(pendulum()))
    with w.locked() as (m, d):
        d.qpos[m.jnt_qposadr[m.joint('p/hinge').id]] = 0.05
    assert period(w, 'p/hinge') == pytest.approx(2 * math.pi * math.sqrt(1.0 / G), rel=0.01)


def test_a_prismatic_spring_oscillates_at_sqrt_k_over_m_about_its_reference():
    k, m_ = 200.0, 2.0
    text = sdf(pendulum('prismatic', f'<axis><xyz>1 0 0</xyz><dynamics><spring_stiffness>{k}'
                                     '</spring_stiffness><spring_reference>0.1</spring_reference>'
                                     '</dynamics></axis>', mass=m_))
    w = load(text)
    q = []
    while w.time < 3.0:
        w.step(1)
        q.append(w.get_joint_states()['p/hinge'][0])
    q = np.array(q)
    assert (q.max() + q.min()) / 2 == pytest.approx(0.1, abs=1e-3)  # about its reference
    ups = np.nonzero((q[:-1] < 0.1) & (q[1:] >= 0.1))[0] * 0.001
    assert float(np.mean(np.diff(ups))) == pytest.approx(2 * math.pi * math.sqrt(m_ / k), rel=0.01)


def test_a_joint_limit_stops_it_and_damping_takes_its_energy():
    w = load(sdf(pendulum(axis='<axis><xyz>1 0 0</xyz><limit><lower>-0.2</lower>'
                               '<upper>0.2</upper></limit><dynamics><damping>5</damping>'
                               '</dynamics></axis>')))
    with w.locked() as (m, d):
        d.qvel[m.jnt_dofadr[m.joint('p/hinge').id]] = 5.0
    peak = 0.0
    for _ in range(3000):
        w.step(1)
        peak = max(peak, abs(w.get_joint_states()['p/hinge'][0]))
    assert peak < 0.205  # the stop holds, as hard as a step allows (SDF's are stiff)
    assert abs(w.get_joint_states()['p/hinge'][1]) < 0.05  # damped down


def test_a_continuous_joint_turns_past_a_whole_turn():
    w = load(sdf(pendulum('continuous', '<axis><xyz>1 0 0</xyz><limit><lower>-0.5</lower>'
                                        '<upper>0.5</upper></limit></axis>')))
    with w.locked() as (m, d):
        assert not m.jnt_limited[m.joint('p/hinge').id]  # its limits are not stops
        d.qvel[m.jnt_dofadr[m.joint('p/hinge').id]] = 20.0
    w.step(1000)
    assert abs(w.get_joint_states()['p/hinge'][0]) > 2 * math.pi


def test_a_joint_whose_limits_are_equal_is_locked_there():
    # Gazebo's way to lock a joint; MuJoCo refuses a range whose ends are equal.
    w = load(sdf(pendulum(axis='<axis><xyz>1 0 0</xyz><limit><lower>0.3</lower>'
                               '<upper>0.3</upper></limit></axis>')))
    with w.locked() as (m, d):
        d.qpos[m.jnt_qposadr[m.joint('p/hinge').id]] = 0.3
    w.step(2000)
    assert w.get_joint_states()['p/hinge'][0] == pytest.approx(0.3, abs=0.005)


def test_a_screw_joint_advances_its_pitch_per_turn():
    pitch = 0.05  # m a turn, right-handed; the axis across gravity, a bob with inertia
    text = sdf(pendulum('screw', '<axis><xyz>0 1 0</xyz></axis>').replace(
        '<axis>', f'<screw_thread_pitch>{pitch}</screw_thread_pitch><axis>', 1).replace(
        '<ixx>1e-6</ixx><iyy>1e-6</iyy><izz>1e-6</izz>', '<ixx>0.1</ixx><iyy>0.1</iyy>'
        '<izz>0.1</izz>'))
    w = load(text)
    with w.locked() as (m, d):
        d.qvel[m.jnt_dofadr[m.joint('p/hinge').id]] = 2.0
    w.step(300)
    js = w.get_joint_states()
    turn, slide = js['p/hinge'][0], js['p/hinge_translation'][0]
    assert turn != 0 and slide == pytest.approx(pitch * turn / (2 * math.pi), rel=0.02)


def test_a_mimic_joint_follows_multiplier_times_leader_minus_reference_plus_offset():
    mimic = ('<mimic joint="hinge"><multiplier>-2</multiplier><offset>0.1</offset>'
             '<reference>0.05</reference></mimic>')
    follower = (box_link('f', pose=at('0 0.5 3 0 0 0'), collide=False)
                + f'<joint name="follow" type="revolute"><parent>base</parent><child>f</child>'
                f'<axis><xyz>0 1 0</xyz>{mimic}</axis></joint>')
    w = load(sdf(pendulum().replace('</model>', follower + '</model>'), version='1.11'))
    with w.locked() as (m, d):
        d.qpos[m.jnt_qposadr[m.joint('p/hinge').id]] = 0.3
    w.step(400)
    js = w.get_joint_states()
    lead, follow = js['p/hinge'][0], js['p/follow'][0]
    assert follow == pytest.approx(-2 * (lead - 0.05) + 0.1, abs=3e-3)


def test_universal_and_ball_joints_move_about_two_and_three_axes():
    w = load(sdf(pendulum('universal', '<axis><xyz>1 0 0</xyz></axis><axis2><xyz>0 1 0</xyz>'
                                       '</axis2>')
                 + pendulum('ball', '').replace('name="p"', 'name="b"')
                 .replace('<pose>0 0 3 0 0 0</pose>', '<pose>4 0 3 0 0 0</pose>')
                 .replace(f'<pose>0 0 {2.0} 0 0 0</pose>', '<pose>4 0 2 0 0 0</pose>')))
    njnt = w.read(lambda m, d: [(m.joint(i).name, int(m.jnt_type[i])) for i in range(m.njnt)])
    kinds = dict(njnt)
    assert kinds['p/hinge'] == kinds['p/hinge_axis2'] == int(mujoco.mjtJoint.mjJNT_HINGE)
    assert kinds['b/hinge'] == int(mujoco.mjtJoint.mjJNT_BALL)


def test_a_joint_that_closes_a_loop_keeps_it_closed():
    """A four-bar linkage: the fourth joint becomes two connects along its axis."""
    links = ''.join(box_link(n, pose=at(f'{x} 0 {z} 0 0 0'), collide=False)
                    for n, x, z in (('crank', 0, 2.5), ('coupler', 0.5, 2), ('rocker', 1, 2.5)))
    joints = ''.join(
        f'<joint name="{n}" type="revolute"><pose relative_to="{c}">{px} 0 {pz} 0 0 0</pose>'
        f'<parent>{p}</parent><child>{c}</child><axis><xyz>0 1 0</xyz></axis></joint>'
        for n, p, c, px, pz in (('j1', 'base', 'crank', 0, 0.5),
                                ('j2', 'crank', 'coupler', -0.5, 0),
                                ('j3', 'base', 'rocker', 0, 0.5),
                                ('j4', 'rocker', 'coupler', 0.5, 0)))
    w = load(sdf('<model name="four">' + box_link('base', pose=at('0.5 0 3 0 0 0')) + links
                 + '<joint name="fix" type="fixed"><parent>world</parent>'
                 '<child>base</child></joint>' + joints + '</model>'))
    with w.locked() as (m, d):
        assert m.neq == 2  # the loop's closure
        d.qvel[m.jnt_dofadr[m.joint('four/j1').id]] = 3.0
    w.step(1000)
    gap = w.read(lambda m, d: np.linalg.norm(
        d.xpos[m.body('four/rocker').id] + d.xmat[m.body('four/rocker').id].reshape(3, 3)
        @ [0, 0, -0.5] - d.xpos[m.body('four/coupler').id]
        - d.xmat[m.body('four/coupler').id].reshape(3, 3) @ [0.5, 0, 0]))
    assert gap < 2e-3


# ------------------------------------------------------------------ surfaces

def slope_world(mu_box: float, mu_ground: float, tan: float) -> World:
    angle = math.atan(tan)
    box = box_link('b', extra=f'<surface><friction><ode><mu>{mu_box}</mu></ode></friction>'
                              '</surface>')
    return load(sdf(
        f'<model name="ramp"><static>true</static><pose>0 0 0 {angle} 0 0</pose>'
        f'<link name="l"><collision name="c"><geometry><box><size>4 4 0.1</size></box>'
        f'</geometry><surface><friction><ode><mu>{mu_ground}</mu></ode></friction></surface>'
        f'</collision></link></model>'
        f'<model name="box"><pose>0 0 {0.1} {angle} 0 0</pose>{box}</model>'))


@pytest.mark.parametrize('mu_box, mu_ground, slides', [
    (0.3, 100.0, True),    # Gazebo takes the smaller: 0.3 < tan 0.4, it slides
    (100.0, 0.3, True),    # either way round
    (0.6, 100.0, False),   # 0.6 > 0.4: it stays
])
def test_the_smaller_friction_of_two_surfaces_decides_as_in_gazebo(mu_box, mu_ground, slides):
    w = slope_world(mu_box, mu_ground, 0.4)
    w.step(200)
    start = w.get_entity_state('box').position.copy()
    w.step(1000)
    moved = float(np.linalg.norm(w.get_entity_state('box').position - start))
    assert (moved > 0.05) == slides, moved


def test_a_bounce_returns_its_restitution_coefficient_of_the_drop():
    e = 0.6
    w = load(sdf(f'<model name="floor"><static>true</static><link name="l"><collision name="c">'
                 f'<geometry><plane><normal>0 0 1</normal></plane></geometry><surface><bounce>'
                 f'<restitution_coefficient>{e}</restitution_coefficient></bounce></surface>'
                 f'</collision></link></model><model name="ball"><pose>0 0 1 0 0 0</pose>'
                 f'<link name="b"><inertial><mass>1</mass><inertia><ixx>0.004</ixx>'
                 f'<iyy>0.004</iyy><izz>0.004</izz></inertia></inertial><collision name="c">'
                 f'<geometry><sphere><radius>0.1</radius></sphere></geometry><surface><bounce>'
                 f'<restitution_coefficient>{e}</restitution_coefficient></bounce></surface>'
                 f'</collision></link></model>'))
    z, peak = [], None
    while w.time < 2.0:
        w.step(1)
        z.append(w.get_entity_state('ball').position[2])
        if len(z) > 2 and z[-2] > z[-3] and z[-2] >= z[-1] and w.time > 0.5:
            peak = z[-2]
            break
    assert peak is not None
    # heights above the contact (radius 0.1): h1 / h0 = e^2
    assert math.sqrt((peak - 0.1) / (1 - 0.1)) == pytest.approx(e, abs=0.06)


def test_links_of_one_model_do_not_collide_unless_it_says_self_collide():
    def model(flag: str) -> str:
        return (f'<model name="m{flag}"><pose>{0 if flag == "false" else 3} 0 1 0 0 0</pose>'
                f'<self_collide>{flag}</self_collide>{box_link("a")}'
                + box_link('b', pose=at('0.05 0 0 0 0 0')) + '</model>')
    w = load(sdf(model('false') + model('true')))
    w.step(300)
    gap = {f: np.linalg.norm((pos(w, f'm{f}') - pos(w, f'm{f}/b'))[:2])
           for f in ('false', 'true')}
    assert gap['false'] == pytest.approx(0.05, abs=1e-4)  # left overlapping, untouched
    assert gap['true'] > 0.09  # pushed apart


# ------------------------------------------------------------------ shapes and looks

def test_each_shape_has_the_size_sdf_means():
    shapes = {'box': '<box><size>1 2 3</size></box>', 'sphere': '<sphere><radius>0.5</radius>'
              '</sphere>', 'cylinder': '<cylinder><radius>0.5</radius><length>2</length>'
              '</cylinder>', 'capsule': '<capsule><radius>0.25</radius><length>1</length>'
              '</capsule>', 'ellipsoid': '<ellipsoid><radii>1 2 3</radii></ellipsoid>'}
    body = ''.join(f'<model name="{k}"><static>true</static><pose>{5 * i} 0 5 0 0 0</pose>'
                   f'<link name="l"><collision name="c"><geometry>{g}</geometry></collision>'
                   f'</link></model>' for i, (k, g) in enumerate(shapes.items()))
    w = load(sdf(body))
    sizes = {k: w.read(lambda m, d, k=k: m.geom(f'{k}/l/c').size.copy()) for k in shapes}
    assert np.allclose(sizes['box'], [0.5, 1, 1.5])
    assert sizes['sphere'][0] == 0.5
    assert np.allclose(sizes['cylinder'][:2], [0.5, 1]) and np.allclose(sizes['capsule'][:2],
                                                                        [0.25, 0.5])
    assert np.allclose(sizes['ellipsoid'], [1, 2, 3])
    lo, hi = w.entity_bounds('capsule')
    assert hi[2] - lo[2] == pytest.approx(1 + 2 * 0.25)  # SDF's length is its cylinder's


def test_a_polyline_is_extruded_and_a_box_lands_on_its_top():
    corners = ((0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2))  # an L
    outline = ''.join(f'<point>{x} {y}</point>' for x, y in corners)
    w = load(sdf(f'<model name="l"><static>true</static><link name="l"><collision name="c">'
                 f'<geometry><polyline>{outline}<height>0.3</height></polyline></geometry>'
                 f'</collision></link></model>'
                 f'<model name="box"><pose>0.5 1.5 1 0 0 0</pose>{box_link("b")}</model>'))
    w.step(1500)
    assert w.get_entity_state('box').position[2] == pytest.approx(0.3 + 0.05, abs=3e-3)

    def corners(m, d):
        g = m.geom('l/l/c').id
        a, n = m.mesh_vertadr[m.geom_dataid[g]], m.mesh_vertnum[m.geom_dataid[g]]
        v = d.geom_xpos[g] + m.mesh_vert[a:a + n] @ d.geom_xmat[g].reshape(3, 3).T
        return v.min(axis=0), v.max(axis=0)
    lo, hi = w.read(corners)
    assert np.allclose(lo, [0, 0, 0], atol=1e-6) and np.allclose(hi, [2, 2, 0.3], atol=1e-6)


def test_a_plane_turned_to_its_normal_holds_a_box_on_it():
    w = load(sdf('<model name="wall"><static>true</static><link name="l"><collision name="c">'
                 '<geometry><plane><normal>0 0 1</normal><size>10 10</size></plane></geometry>'
                 '</collision></link></model><model name="tilted"><static>true</static>'
                 '<pose>0 0 -5 0 0 0</pose><link name="l"><collision name="c"><geometry><plane>'
                 '<normal>1 0 0</normal></plane></geometry></collision></link></model>'
                 f'<model name="box"><pose>0 0 0.5 0 0 0</pose>{box_link("b")}</model>'))
    w.step(800)
    assert w.get_entity_state('box').position[2] == pytest.approx(0.05, abs=2e-3)
    normal = w.read(lambda m, d: d.geom_xmat[m.geom('tilted/l/c').id].reshape(3, 3)[:, 2])
    assert np.allclose(normal, [1, 0, 0], atol=1e-9)


def test_materials_give_diffuse_colour_script_colour_and_transparency():
    def visual(name: str, material: str, extra: str = '') -> str:
        return (f'<model name="{name}"><static>true</static><link name="l"><visual name="v">'
                f'<geometry><sphere><radius>0.1</radius></sphere></geometry>{extra}'
                f'<material>{material}</material></visual></link></model>')
    w = load(sdf(visual('red', '<diffuse>1 0 0 1</diffuse><ambient>0 1 0 1</ambient>')
                 + visual('grey', '<script><name>Gazebo/Grey</name></script>')
                 + visual('clear', '<diffuse>0 0 1 1</diffuse>', '<transparency>0.75'
                                                                 '</transparency>')))
    rgba = {n: w.read(lambda m, d, n=n: m.mat_rgba[m.geom_matid[m.geom(f'{n}/l/v').id]].copy())
            for n in ('red', 'grey', 'clear')}
    assert np.allclose(rgba['red'], [1, 0, 0, 1])
    assert np.allclose(rgba['grey'][:3], [0.7] * 3)
    assert rgba['clear'][3] == pytest.approx(0.25)


def test_a_pbr_albedo_map_textures_the_visual(tmp_path):
    from PIL import Image
    Image.new('RGB', (4, 4), (200, 30, 30)).save(tmp_path / 'brick.png')
    w = load(sdf('<model name="wall"><static>true</static><link name="l"><visual name="v">'
                 '<geometry><box><size>1 1 1</size></box></geometry><material><pbr><metal>'
                 '<albedo_map>brick.png</albedo_map></metal></pbr></material></visual></link>'
                 '</model>'), tmp_path, resource_paths=[str(tmp_path)])
    tex = w.read(lambda m, d: int(m.mat_texid[m.geom_matid[m.geom('wall/l/v').id]][1]))
    assert tex >= 0  # MuJoCo's RGB role holds the image


def test_a_heightmap_is_a_height_field_of_its_size_and_a_box_rests_on_it(tmp_path):
    from PIL import Image
    image = Image.new('L', (5, 5), 0)
    for x in range(1, 4):
        for y in range(1, 4):
            image.putpixel((x, y), 255)  # a plateau at the full height
    image.save(tmp_path / 'hill.png')
    w = load(sdf('<model name="hill"><static>true</static><link name="l"><collision name="c">'
                 '<geometry><heightmap><uri>hill.png</uri><size>4 4 1</size><pos>0 0 0.2</pos>'
                 '</heightmap></geometry></collision></link></model>'
                 f'<model name="box"><pose>0 0 2 0 0 0</pose>{box_link("b")}</model>'),
             tmp_path, resource_paths=[str(tmp_path)])
    size = w.read(lambda m, d: m.hfield_size[0].copy())
    assert np.allclose(size[:3], [2, 2, 1])  # half extents, the height range
    w.step(1500)
    assert w.get_entity_state('box').position[2] == pytest.approx(0.2 + 1 + 0.05, abs=5e-3)


def test_surface_and_joint_details_map_as_documented():
    box = '<geometry><box><size>0.1 0.1 0.1</size></box></geometry>'
    surface = ('<surface><friction><ode><mu>0.5</mu><mu2>0.9</mu2></ode><torsional>'
               '<coefficient>2</coefficient><patch_radius>0.01</patch_radius></torsional>'
               '</friction><contact><collide_bitmask>0x02</collide_bitmask>'
               '<ode><kp>1000</kp><kd>10</kd></ode></contact></surface>')
    w = load(sdf('<model name="m"><link name="l"><inertial><mass>2</mass><inertia><ixx>0.01'
                 f'</ixx><iyy>0.01</iyy><izz>0.01</izz></inertia></inertial><collision name="c">'
                 f'{box}{surface}</collision></link></model>'
                 + pendulum(axis='<axis><xyz>1 0 0</xyz><dynamics><friction>0.7</friction>'
                                 '</dynamics></axis>')))
    g = w.read(lambda m, d: (m.geom_friction[m.geom('m/l/c').id].copy(),
                             int(m.geom_condim[m.geom('m/l/c').id]),
                             m.geom_solref[m.geom('m/l/c').id].copy(),
                             int(m.geom_contype[m.geom('m/l/c').id]),
                             int(m.geom_conaffinity[m.geom('m/l/c').id]),
                             float(m.dof_frictionloss[m.jnt_dofadr[m.joint('p/hinge').id]])))
    friction, condim, solref, contype, conaffinity, frictionloss = g
    assert friction[0] == 0.5  # isotropic: mu2 read as mu
    assert friction[1] == pytest.approx(2 * 0.01) and condim == 4  # torsional: coefficient r
    assert np.allclose(solref, [-1000 / 2, -10 / 2])  # kp, kd per unit of the link's mass
    assert (contype, conaffinity) == (2, 2)
    assert frictionloss == 0.7


def test_a_submesh_is_named_and_its_whole_file_drawn(tmp_path):
    from sim_node.core.models.collada_fast import binary_stl
    corners = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    (tmp_path / 'parts.stl').write_bytes(binary_stl(corners, np.array(
        [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])))
    plan = world_sources.world_source(
        sdf('<model name="m"><static>true</static><link name="l"><visual name="v"><geometry>'
            '<mesh><uri>parts.stl</uri><submesh><name>lid</name></submesh></mesh></geometry>'
            '</visual></link></model>'), str(tmp_path), [str(tmp_path)],
        places=sdf_files.Places.of(environ={}))
    assert any("<submesh> 'lid'" in n for n in plan.notes), plan.notes
    assert World.from_plan(plan).read(lambda m, d: m.nmesh) == 1


# ------------------------------------------------------------------ files and models

def model_folder(root: Path, name: str, body: str, versions=(('1.6', 'model.sdf'),)) -> Path:
    folder = root / name
    folder.mkdir(parents=True)
    entries = ''.join(f'<sdf version="{v}">{f}</sdf>' for v, f in versions)
    (folder / 'model.config').write_text(f'<?xml version="1.0"?><model><name>{name}</name>'
                                         f'{entries}</model>')
    for _, f in versions:
        (folder / f).write_text(f'<?xml version="1.0"?><sdf version="1.9">{body}</sdf>')
    return folder


def test_model_uris_resolve_on_gazebos_paths_model_config_naming_the_newest_file(tmp_path):
    models = tmp_path / 'models'
    model_folder(models, 'crate', f'<model name="crate">{box_link("c")}</model>')
    folder = model_folder(models, 'versioned', '<model name="v"/>',
                          (('1.5', 'old.sdf'), ('1.9', 'new.sdf')))
    (folder / 'new.sdf').write_text(f'<sdf version="1.9"><model name="v">{box_link("n")}'
                                    '</model></sdf>')
    text = sdf('<include><uri>model://crate</uri><name>a</name><pose>1 0 1 0 0 0</pose>'
               '</include><include><uri>model://crate</uri><name>b</name><static>true</static>'
               '<pose>2 0 1 0 0 0</pose></include><include><uri>model://versioned</uri>'
               '</include>')
    w = load(text, environ={'GZ_SIM_RESOURCE_PATH': str(models)})
    cats = {e.name: e.category for e in w.entities()}
    assert cats == {'a': 'dynamic', 'b': 'static', 'v': 'dynamic'}
    assert w.read(lambda m, d: m.body('v').name) == 'v'  # the 1.9 file's link n is the root
    assert np.allclose(w.get_entity_state('b').position, [2, 0, 1])


def test_a_models_relative_mesh_resolves_in_its_own_folder_and_scales(tmp_path):
    import trimesh
    models = tmp_path / 'models'
    folder = model_folder(models, 'tray', '<model name="tray"><static>true</static><link '
                                          'name="l"><visual name="v"><geometry><mesh><uri>'
                                          'meshes/cube.obj</uri><scale>2 1 1</scale></mesh>'
                                          '</geometry></visual></link></model>')
    (folder / 'meshes').mkdir()
    trimesh.creation.box((1, 1, 1)).export(folder / 'meshes' / 'cube.obj')
    w = load(sdf('<include><uri>model://tray</uri></include>'), tmp_path,
             environ={'GAZEBO_MODEL_PATH': str(models)})
    lo, hi = w.entity_bounds('tray')
    assert np.allclose(hi - lo, [2, 1, 1], atol=1e-6)


def test_a_fuel_uri_reads_the_newest_cached_version(tmp_path):
    cache = tmp_path / 'fuel'
    for version, size in (('1', '1 1 1'), ('3', '2 2 2')):
        base = cache / 'fuel.gazebosim.org' / 'openrobotics' / 'models' / 'table' / version
        base.mkdir(parents=True)
        (base / 'model.config').write_text('<model><sdf version="1.6">model.sdf</sdf></model>')
        (base / 'model.sdf').write_text(
            f'<sdf version="1.6"><model name="Table"><static>true</static><link name="l">'
            f'<collision name="c"><geometry><box><size>{size}</size></box></geometry>'
            f'</collision></link></model></sdf>')
    w = load(sdf('<include><uri>https://fuel.gazebosim.org/1.0/OpenRobotics/models/Table'
                 '</uri></include>'), environ={'GZ_FUEL_CACHE_PATH': str(cache)})
    lo, hi = w.entity_bounds('Table')
    assert np.allclose(hi - lo, [2, 2, 2])


@pytest.mark.parametrize('variable', ['GZ_SIM_RESOURCE_PATH', 'IGN_GAZEBO_RESOURCE_PATH',
                                      'GAZEBO_MODEL_PATH', None])
def test_each_of_gazebos_model_paths_and_the_resource_paths_finds_a_model(tmp_path, variable):
    models = tmp_path / 'models'
    model_folder(models, 'crate', f'<model name="crate">{box_link("c")}</model>')
    text = sdf('<include><uri>model://crate</uri></include>')
    if variable is None:  # the node's resource_paths
        w = load(text, environ={}, resource_paths=[str(models)])
    else:
        w = load(text, environ={variable: f'/nowhere:{models}'})
    assert 'crate' in {e.name for e in w.entities()}


def test_an_uncached_fuel_model_is_a_missing_asset_that_says_how_to_fetch_it(tmp_path):
    from sim_node.core.errors import MissingAssetsError
    with pytest.raises(MissingAssetsError, match='fuel.gazebosim.org.*Shelf'):
        load(sdf('<include><uri>https://fuel.gazebosim.org/1.0/OpenRobotics/models/Shelf'
                 '</uri></include>'), environ={'GZ_FUEL_CACHE_PATH': str(tmp_path)})


def test_an_include_merged_into_a_model_keeps_its_links_where_they_were(tmp_path):
    models = tmp_path / 'models'
    model_folder(models, 'arm', '<model name="arm">' + box_link('a', pose=at('0 0 1 0 0 0'))
                 + '</model>')
    w = load(sdf(f'<model name="robot"><static>true</static>{box_link("base")}<include '
                 f'merge="true"><uri>model://arm</uri><pose>5 0 0 0 0 0</pose></include>'
                 f'</model>'), environ={'GZ_SIM_RESOURCE_PATH': str(models)})
    forward(w)
    assert np.allclose(pos(w, 'robot/a'), [5, 0, 1])
    assert [e.name for e in w.entities()] == ['robot']


def test_a_spawned_sdf_model_takes_its_pose_from_the_spawn_and_its_name_from_the_file():
    text = f'<sdf version="1.9"><model name="crate"><pose>9 9 9 0 0 0</pose>{box_link("c")}' \
           f'<link name="lid"><pose>0 0 0.2 0 0 0</pose></link></model></sdf>'
    src = sources.from_model_text(text)
    w = World.from_file(str(Path(__file__).parent.parent / 'scenes' / 'empty.xml'))
    name = w.spawn('', src, (1, 2, 0.5))
    forward(w)
    assert name == 'crate' and np.allclose(pos(w, 'crate'), [1, 2, 0.5])
    assert np.allclose(pos(w, 'crate/lid'), [1, 2, 0.7])


# ------------------------------------------------------------------ what is not read

def test_elements_not_read_are_named_and_refused_when_asked():
    text = sdf(f'<model name="m">{box_link("a")}<gripper name="g"/></model><road name="r"/>'
               '<gz:policies><x>1</x></gz:policies>')
    plan = world_sources.world_source(text)
    assert plan.dropped == ['model/gripper', 'world/gz:policies', 'world/road']
    with pytest.raises(UnsupportedElementsError, match='road'):
        world_sources.world_source(text, fail_on_unsupported_element=True)


def test_the_docs_table_is_the_one_the_reader_uses():
    docs = (Path(__file__).parent.parent / 'docs' / 'sdf.md').read_text()
    assert sdf_elements.markdown() in docs


def test_a_world_system_with_no_meaning_here_is_silent_and_another_is_named(caplog):
    lift = ('<plugin filename="gz-sim-lift-drag-system" name="gz::sim::systems::LiftDrag"/>'
            '<plugin filename="gz-sim-joint-state-publisher-system" '
            'name="gz::sim::systems::JointStatePublisher"/>')
    w = load(sdf(
        '<plugin filename="gz-sim-physics-system" name="gz::sim::systems::Physics"/>'
        '<plugin filename="libgz-sim-sensors-system.so" name="gz::sim::systems::Sensors"/>'
        '<plugin filename="gz-sim-wind-effects-system" name="gz::sim::systems::WindEffects"/>'
        f'<model name="glider">{box_link("wing")}{lift}</model>'))
    assert w.systems_not_run() == {'world': ('WindEffects',), 'glider': ('LiftDrag',)}
    said = [r.getMessage() for r in caplog.records if 'not run here' in r.getMessage()]
    assert len(said) == 2 and 'WindEffects' in said[0] + said[1], said  # once each
    assert not any('Physics' in t or 'Sensors' in t or 'JointState' in t for t in said)
    # A spawned model's go with it.
    w.spawn('kite', sources.from_model_text(
        f'<sdf version="1.9"><model name="kite">{box_link("sail")}{lift}</model></sdf>'),
        position=(3.0, 0.0, 1.0))
    assert w.systems_not_run()['kite'] == ('LiftDrag',)
    w.delete('kite')
    assert 'kite' not in w.systems_not_run()


def test_a_link_pose_that_is_not_a_number_is_refused_naming_it():
    with pytest.raises(ResourceParseError, match="link 'a' of the model 'm'.*nan"):
        load(sdf('<model name="m">' + box_link('a', pose=at('0 0 nan 0 0 0')) + '</model>'))
