"""
An SDF model's sensors in the core (issue 54, item 3): their topics, frames, rates and readings.

gz-sim names a sensor's topic ``/world/<w>/model/<m>/link/<l>/sensor/<s>/<kind>`` where it
names none and its frame ``<m>/<l>/<s>`` (its scoped name, through ros_gz_bridge) where no
``<gz_frame_id>`` names one; here that frame is at the sensor's pose. A magnetometer reads the
world's field in its frame; a NavSat the WGS84 point of its position in the local tangent plane
of the world's ``<spherical_coordinates>``: both are checked against the geodesy, not the code.
"""

import math

import numpy as np
import pytest
from sim_node.core.base.config import WorldConfig
from sim_node.core.base.records import DeclaredGeo
from sim_node.core.models import sdf_files, sources, world_sources
from sim_node.core.stepping.geo import GeoSample
from sim_node.core.world import World

LAT, LON, ELEVATION = 48.0, 11.0, 500.0
FIELD = (1e-5, 2e-5, -4e-5)
A, F = 6378137.0, 1 / 298.257223563  # WGS84
E2 = F * (2 - F)


def sensor(kind: str, name: str, extra: str = '') -> str:
    return f'<sensor name="{name}" type="{kind}"><update_rate>50</update_rate>{extra}</sensor>'


def probe(name: str, pose: str, sensors: str) -> str:
    return (f'<model name="{name}"><static>true</static><pose>{pose}</pose><link name="body">'
            '<inertial><mass>1</mass><inertia><ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz>'
            f'</inertia></inertial>{sensors}</link></model>')


ALL = (sensor('gpu_lidar', 'lidar', '<pose>0.15 0 0.1 0 0 0</pose><lidar><scan><horizontal>'
              '<samples>90</samples><min_angle>-1.5</min_angle><max_angle>1.5</max_angle>'
              '</horizontal></scan><range><min>0.1</min><max>10</max></range></lidar>')
       + sensor('imu', 'imu', '<topic>/probe/imu</topic><pose>0 0 0.05 0 0 1.5707963</pose>')
       + sensor('imu', 'named', '<gz_frame_id>body</gz_frame_id>')
       + sensor('camera', 'cam', '<camera><image><width>64</width><height>48</height>'
                '</image></camera>')
       + sensor('depth_camera', 'depth', '<camera><image><width>32</width><height>24</height>'
                '</image></camera>')
       + sensor('magnetometer', 'mag') + sensor('navsat', 'gps'))


def world(models: str, coordinates: bool = True, field: bool = True) -> World:
    coords = (f'<spherical_coordinates><surface_model>EARTH_WGS84</surface_model>'
              f'<latitude_deg>{LAT}</latitude_deg><longitude_deg>{LON}</longitude_deg>'
              f'<elevation>{ELEVATION}</elevation><heading_deg>0</heading_deg>'
              '</spherical_coordinates>') if coordinates else ''
    magnetic = f'<magnetic_field>{" ".join(map(str, FIELD))}</magnetic_field>' if field else ''
    text = (f'<?xml version="1.0"?><sdf version="1.9"><world name="w">{coords}{magnetic}'
            f'{models}</world></sdf>')
    plan = world_sources.world_source(text, None, places=sdf_files.Places.of())
    return World.from_plan(plan, WorldConfig(), 'test')


def samples(w: World, seconds: float = 1.0) -> list:
    w.take_sensor_samples()
    w.step(int(round(seconds / w.timestep)))
    return [s for s in w.take_sensor_samples() if isinstance(s, GeoSample)]


def test_topics_and_frames_are_gz_sims_and_a_frame_is_where_its_sensor_is():
    info = world(probe('probe', '0 0 0 0 0 0', ALL)).snapshot().info
    base = '/world/w/model/probe/link/body/sensor'
    laser = info.lasers['probe/lidar_lidar']
    assert laser.topic == f'{base}/lidar/scan' and laser.samples == 90
    assert laser.frame == 'probe/body/lidar' and laser.own_frame
    imus = {d.site: d for d in info.imus.values()}
    assert imus['probe/imu_imu'].topic == '/probe/imu'
    assert imus['probe/imu_imu'].frame == 'probe/body/imu'
    assert imus['probe/named_imu'].frame == 'probe/body'  # gz_frame_id names a link
    assert not imus['probe/named_imu'].own_frame
    frames = dict(info.sensor_frames)
    assert frames['probe/lidar_lidar'] == 'probe/body/lidar'
    assert 'probe/named_imu' not in frames
    sites = {s.name: s for s in info.sites}
    assert np.allclose(sites['probe/lidar_lidar'].pos, [0.15, 0, 0.1])  # the frame's place
    assert np.allclose(sites['probe/imu_imu'].quat_wxyz, [math.sqrt(0.5), 0, 0, math.sqrt(0.5)],
                       atol=1e-6)
    cams = info.cameras_declared
    assert cams['probe/cam'].image_topic == f'{base}/cam/image'
    assert cams['probe/cam'].info_topic == f'{base}/cam/camera_info'
    assert cams['probe/depth'].depth_topic == f'{base}/depth/depth_image'
    assert (cams['probe/cam'].width, cams['probe/cam'].height) == (64, 48)
    geo = {d.kind: d for d in info.geo.values()}
    assert geo['magnetometer'].topic == f'{base}/mag/magnetometer'
    assert geo['navsat'].topic == f'{base}/gps/navsat'
    assert geo['navsat'].frame == 'probe/body/gps' and geo['navsat'].rate_hz == 50
    assert info.spherical == (LAT, LON, ELEVATION, 0.0)


def radii(lat_deg: float) -> tuple:
    """Return WGS84's meridional and prime-vertical radii of curvature at a latitude (m)."""
    s2 = math.sin(math.radians(lat_deg)) ** 2
    return A * (1 - E2) / (1 - E2 * s2) ** 1.5, A / math.sqrt(1 - E2 * s2)


def test_a_navsat_reads_where_it_is_on_the_earth():
    gps = sensor('navsat', 'gps')
    w = world(probe('here', '0 0 0 0 0 0', gps) + probe('east', '100 0 0 0 0 0', gps)
              + probe('north', '0 100 0 0 0 0', gps) + probe('up', '0 0 10 0 0 0', gps))
    fixes = {s.site.split('/')[0]: s.value for s in samples(w)}
    m, n = radii(LAT)
    assert fixes['here'] == pytest.approx((LAT, LON, ELEVATION), abs=1e-9)
    # 100 m east: the longitude turns by 100 m over the parallel's radius (N + h) cos(lat)
    d_lon = math.degrees(100.0 / ((n + ELEVATION) * math.cos(math.radians(LAT))))
    assert fixes['east'][1] - LON == pytest.approx(d_lon, rel=1e-6)
    assert fixes['east'][0] == pytest.approx(LAT, abs=1e-6)  # the plane leaves the parallel
    # 100 m north: the latitude turns by 100 m over the meridian's radius M + h
    assert fixes['north'][0] - LAT == pytest.approx(math.degrees(100.0 / (m + ELEVATION)),
                                                    rel=1e-6)
    assert fixes['up'][2] == pytest.approx(ELEVATION + 10.0, abs=1e-6)


def test_a_magnetometer_reads_the_field_in_its_frame_at_its_rate():
    mag = sensor('magnetometer', 'mag')
    w = world(probe('level', '0 0 0 0 0 0', mag) + probe('turned', '1 0 0 0 0 1.5707963', mag))
    got = samples(w)
    by = {s.site.split('/')[0]: s for s in got}
    assert by['level'].value == pytest.approx(FIELD, abs=1e-12)
    bx, by_, bz = FIELD  # a quarter turn left: its x is the world's y, its y the world's -x
    assert by['turned'].value == pytest.approx((by_, -bx, bz), abs=1e-11)
    times = sorted(s.time for s in got if s.site.startswith('level/'))
    assert len(times) in (50, 51) and np.allclose(np.diff(times[1:]), 0.02)  # then on time


def test_a_world_without_a_field_or_coordinates_has_sdfs_defaults():
    w = world(probe('p', '0 0 0 0 0 0', sensor('magnetometer', 'mag') +
                    sensor('navsat', 'gps')), coordinates=False, field=False)
    got = {s.kind: s.value for s in samples(w, 0.1)}
    assert got['magnetometer'] == pytest.approx((5.5645e-6, 22.8758e-6, -42.3884e-6), rel=1e-4)
    assert got['navsat'] == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)


def test_a_urdf_magnetometer_and_gps_are_sampled_too():
    robot = """<robot name="r"><link name="base"><inertial><mass value="1"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
      <gazebo reference="base"><sensor name="compass" type="magnetometer">
        <update_rate>20</update_rate><topic>compass</topic></sensor>
        <sensor name="fix" type="gps"/></gazebo>
      <gazebo><static>true</static></gazebo></robot>"""
    w = world('')
    w.spawn('r', sources.from_model_text(robot), position=(0.0, 0.0, 1.0))
    geo = w.snapshot().info.geo
    assert geo['r/compass_magnetometer'] == DeclaredGeo(
        site='r/compass_magnetometer', kind='magnetometer', rate_hz=20.0, frame='r/base',
        topic='compass')
    assert geo['r/fix_navsat'].kind == 'navsat' and geo['r/fix_navsat'].topic == ''
    kinds = [s.kind for s in samples(w)]
    assert kinds.count('magnetometer') in (20, 21) and 'navsat' in kinds


@pytest.mark.parametrize('coords', ['<latitude_deg>95</latitude_deg>',
                                    '<latitude_deg>nan</latitude_deg>'])
def test_coordinates_off_the_earth_are_refused(coords):
    from sim_node.core.errors import ResourceParseError
    with pytest.raises(ResourceParseError, match='spherical_coordinates'):
        world_sources.world_source(
            f'<sdf version="1.9"><world name="w"><spherical_coordinates>{coords}'
            '</spherical_coordinates></world></sdf>', None, places=sdf_files.Places.of())


def test_a_joints_force_torque_and_a_links_contact_sensor_take_gz_sims_topics():
    i = '<inertia><ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz></inertia>'
    box = '<geometry><box><size>0.2 0.2 0.2</size></box></geometry>'
    arm = (f'<model name="arm"><link name="base"><pose>0 0 1 0 0 0</pose><inertial><mass>1'
           f'</mass>{i}</inertial></link><link name="weight"><pose>0 0 0.5 0 0 0</pose>'
           f'<inertial><mass>2</mass>{i}</inertial><collision name="c">{box}</collision>'
           '<sensor name="bump" type="contact"><contact><collision>c</collision></contact>'
           '</sensor></link>'
           '<joint name="fix" type="fixed"><parent>world</parent><child>base</child></joint>'
           '<joint name="hang" type="revolute"><parent>base</parent><child>weight</child>'
           '<axis><xyz>1 0 0</xyz></axis><sensor name="ft" type="force_torque">'
           '<update_rate>50</update_rate></sensor></joint></model>')
    info = world(arm).snapshot().info
    (wrench,) = info.wrenches.values()
    assert wrench.topic == '/world/w/model/arm/joint/hang/sensor/ft/forcetorque'
    (contact,) = info.contacts.values()
    assert contact.topic == '/world/w/model/arm/link/weight/sensor/bump/contact'
    assert len(contact.geoms) == 1  # the link's one collision
