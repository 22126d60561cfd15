"""
The MoveIt-style example (examples/follow_trajectory.py) against a real node in real time.

robosuite's panda from the corpus, spawned by file:// URI: a three-point trajectory on its
seven joints succeeds, then a slow one canceled midway leaves the joints where they were.
"""

import importlib.util
from pathlib import Path
import sys

from conftest import serve_node
import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'ros_env'))
import corpus  # noqa: E402, I100

STATUS_CANCELED = 5


@pytest.fixture(scope='module')
def node():
    folder = corpus.fetch()
    yield from serve_node(f'resource_paths:=["{folder}"]')


def test_the_example_drives_a_seven_joint_arm_then_cancels_midway(node, rclpy_context):
    spec = importlib.util.spec_from_file_location('follow_trajectory',
                                                  ROOT / 'examples' / 'follow_trajectory.py')
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    panda = next(m for m in corpus.MODELS if 'panda' in m.path)
    r = example.main(panda.file.as_uri())
    assert len(r['joints']) == 7
    assert r['error_code'] == 0
    assert r['worst_error'] < 0.05  # computed-torque PD through the motors, default gains
    assert r['canceled_status'] == STATUS_CANCELED
    moved = r['held'][0] - r['start'][0]
    assert 0.05 < moved < 0.75  # stopped on the way to +0.8
