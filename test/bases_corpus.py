"""
Mobile bases nobody tuned for this simulator, written as their authors would (issue 44).

:func:`write` puts each into a folder and returns {name: path}. They are shaped after real
robots' description files: a mobile manipulator's base (two wheels named left and right, a
fixed caster as a sphere or as a mesh, no Gazebo tags, default friction), a four-wheel
skid-steer, a holonomic planar base as robot-learning suites drive theirs (slide, slide and
hinge joints under velocity actuators, kv 1000, a force range of 600 N, joint friction loss of
250 N), and a base with a Gazebo diff-drive plugin.
"""

from pathlib import Path

INERTIA = '<inertia ixx="{i}" iyy="{i}" izz="{i}" ixy="0" ixz="0" iyz="0"/>'
#: Wheel radius and the distance between the wheels' middles, as the URDFs have them.
RADIUS, SEPARATION = 0.08, 0.44


def _link(name: str, mass: float, geometry: str, origin: str = '', inertia: float = 0.05,
          collision: str = '', com: str = '') -> str:
    collision = collision or geometry
    return (f'<link name="{name}"><inertial><mass value="{mass}"/>{com or origin}'
            f'{INERTIA.format(i=inertia)}</inertial>'
            f'<visual>{origin}<geometry>{geometry}</geometry></visual>'
            f'<collision>{origin}<geometry>{collision}</geometry></collision></link>')


def _wheel(side: str, y: float, x: float = 0.0, prefix: str = '') -> str:
    name = f'{prefix}{side}_wheel'
    cyl = f'<cylinder radius="{RADIUS}" length="0.04"/>'
    return (_link(name, 1.0, cyl, '<origin rpy="1.5708 0 0"/>', 0.003)
            + f'<joint name="{name}_joint" type="continuous"><parent link="base_link"/>'
            f'<child link="{name}"/><origin xyz="{x} {y} 0"/><axis xyz="0 1 0"/>'
            '<limit effort="20" velocity="12"/></joint>')


def _base(mass: float = 25.0, com_x: float = -0.08) -> str:
    # The chassis clears the ground (its box's bottom 0.06 m above it); its mass sits behind
    # the axle, as an arm's and a battery's do, so the caster carries a share of the weight.
    box = '<box size="0.5 0.4 0.1"/>'
    return _link('base_link', mass, box, '<origin xyz="0 0 0.03"/>', 0.5,
                 com=f'<origin xyz="{com_x} 0 0.03"/>')


def _caster(geometry: str, link: str = 'caster_link') -> str:
    # behind the axle, its bottom on the ground with the wheels (centre 0.08 m up)
    return (_link(link, 0.5, geometry, inertia=0.001)
            + f'<joint name="{link}_joint" type="fixed"><parent link="base_link"/>'
            f'<child link="{link}"/><origin xyz="-0.2 0 -0.045"/></joint>')


def _robot(name: str, *parts: str) -> str:
    return f'<?xml version="1.0"?><robot name="{name}">{"".join(parts)}</robot>'


def caster_sphere() -> str:
    return _robot('caster_sphere', _base(), _wheel('left', SEPARATION / 2),
                  _wheel('right', -SEPARATION / 2), _caster('<sphere radius="0.035"/>'))


def caster_mesh() -> str:
    return _robot('caster_mesh', _base(), _wheel('left', SEPARATION / 2),
                  _wheel('right', -SEPARATION / 2),
                  # a mesh whose link's name does not say what it is
                  _caster('<mesh filename="omni_wheel.stl"/>', link='rear_support'))


def mobile_mast() -> str:
    """Return a mobile manipulator's base with a mast: its origin below the axles, mesh high."""
    mast = ('<link name="link_mast"><inertial><mass value="3.0"/>'
            f'<origin xyz="0 0 0.6"/>{INERTIA.format(i=0.1)}</inertial>'
            '<visual><origin xyz="0 0 0.6"/><geometry><mesh filename="omni_wheel.stl" '
            'scale="2 2 12"/></geometry></visual>'
            '<collision><origin xyz="0 0 0.6"/><geometry><mesh filename="omni_wheel.stl" '
            'scale="2 2 12"/></geometry></collision></link>'
            '<joint name="mast_joint" type="fixed"><parent link="base_link"/>'
            '<child link="link_mast"/><origin xyz="0.1 0 -0.05"/></joint>')
    return _robot('mobile_mast', _base(), _wheel('left', SEPARATION / 2),
                  _wheel('right', -SEPARATION / 2), _caster('<sphere radius="0.035"/>'), mast)


def skid_steer() -> str:
    return _robot('skid', _base(30.0, com_x=0.0),  # four wheels carry it: its middle
                  *(_wheel(side, y, x, prefix)
                    for prefix, x in (('front_', 0.17), ('rear_', -0.17))
                    for side, y in (('left', SEPARATION / 2), ('right', -SEPARATION / 2))))


def gazebo_plugin() -> str:
    plugin = ('<gazebo><plugin name="diff_drive" filename="libgazebo_ros_diff_drive.so">'
              '<left_joint>left_wheel_joint</left_joint><right_joint>right_wheel_joint'
              f'</right_joint><wheel_separation>{SEPARATION}</wheel_separation>'
              f'<wheel_diameter>{2 * RADIUS}</wheel_diameter><max_wheel_torque>20'
              '</max_wheel_torque><odometry_frame>odom</odometry_frame>'
              '<robot_base_frame>base_link</robot_base_frame></plugin></gazebo>')
    return _robot('plugin_base', _base(), _wheel('left', SEPARATION / 2),
                  _wheel('right', -SEPARATION / 2), _caster('<sphere radius="0.035"/>'),
                  plugin)


HOLONOMIC = """<mujoco model="holonomic">
  <option timestep="0.002"/>
  <worldbody>
    <body name="mount" pos="0 0 0.1">
      <joint name="base_x" type="slide" axis="1 0 0" frictionloss="250" damping="10"/>
      <joint name="base_y" type="slide" axis="0 1 0" frictionloss="250" damping="10"/>
      <joint name="base_yaw" type="hinge" axis="0 0 1" frictionloss="250" damping="10"/>
      <geom type="box" size="0.3 0.25 0.08" mass="40" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
  <actuator>
    <velocity name="drive_x" joint="base_x" kv="1000" ctrlrange="-1 1" forcerange="-600 600"/>
    <velocity name="drive_y" joint="base_y" kv="1000" ctrlrange="-1 1" forcerange="-600 600"/>
    <velocity name="drive_yaw" joint="base_yaw" kv="1000" ctrlrange="-1.5 1.5"
              forcerange="-600 600"/>
  </actuator>
</mujoco>
"""


def omni_wheel_stl() -> bytes:
    """Return a caster's omni wheel as a binary STL: a squat polyhedron of 0.035 m radius."""
    import trimesh
    wheel = trimesh.creation.icosphere(subdivisions=2, radius=0.035)
    wheel.apply_scale((1.0, 0.6, 1.0))  # thinner across its rolling plane
    return wheel.export(file_type='stl')


def write(folder: Path) -> dict:
    """Write every base of the corpus into `folder`; return {name: path}."""
    folder = Path(folder)
    (folder / 'omni_wheel.stl').write_bytes(omni_wheel_stl())
    files = {'caster_sphere': ('caster_sphere.urdf', caster_sphere()),
             'caster_mesh': ('caster_mesh.urdf', caster_mesh()),
             'skid_steer': ('skid_steer.urdf', skid_steer()),
             'holonomic': ('holonomic.xml', HOLONOMIC),
             'gazebo_plugin': ('gazebo_plugin.urdf', gazebo_plugin()),
             'mobile_mast': ('mobile_mast.urdf', mobile_mast())}
    out = {}
    for name, (file, text) in files.items():
        (folder / file).write_text(text)
        out[name] = folder / file
    return out
