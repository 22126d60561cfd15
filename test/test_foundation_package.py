"""The package as colcon installs it, and the locally built interfaces."""

import glob
import json
import os
from pathlib import Path
import shutil
import subprocess
import sys

from conftest import installed_prefix, node_executable, ROOT
import pytest

REFERENCE_HASHES = json.loads((ROOT / 'test' / 'interface_type_hashes.json').read_text())


@pytest.mark.parametrize('package', ['tf2_msgs', 'simulation_interfaces', 'control_msgs',
                                     'controller_manager_msgs', 'ros_gz_interfaces'])
def test_interfaces_are_wire_identical_to_the_released_ones(package):
    from ament_index_python.packages import get_package_share_directory
    share = Path(get_package_share_directory(package))
    files = glob.glob(str(share / '**' / '*.json'), recursive=True)
    hashes = {}
    for f in files:
        for entry in json.loads(Path(f).read_text()).get('type_hashes', []):
            hashes[entry['type_name']] = entry['hash_string']
    expected = {k: v for k, v in REFERENCE_HASHES.items() if k.startswith(package + '/')}
    assert expected, 'no reference hashes for ' + package
    missing = sorted(set(expected) - set(hashes))
    assert not missing, f'types not built: {missing}'
    wrong = {k: (hashes[k], v) for k, v in expected.items() if hashes[k] != v}
    assert not wrong, f'type hashes differ from the released ones: {wrong}'


def test_node_executable_is_installed_where_ros2_run_looks_and_not_on_path():
    exe = node_executable()
    assert exe.is_file() and os.access(exe, os.X_OK)
    assert not (installed_prefix() / 'bin' / 'node').exists()
    found = shutil.which('node')
    assert found is None or Path(found).resolve() != exe.resolve()


def test_scenes_install_under_share_keeping_subfolders():
    share = installed_prefix() / 'share' / 'sim'
    for rel in ['scenes/default.xml', 'scenes/objects/box.xml', 'scenes/objects/pyramid.obj']:
        assert (share / rel).is_file(), rel
    assert (share / 'package.xml').is_file()
    assert (installed_prefix() / 'share' / 'ament_index' / 'resource_index' / 'packages'
            / 'sim').is_file()


def test_local_interface_definitions_are_hidden_from_colcon_workspaces():
    assert (ROOT / 'ros_env' / 'COLCON_IGNORE').is_file()


def test_core_imports_no_ros():
    code = ('import sys; import sim_node.core.world, sim_node.core.loop, '
            'sim_node.core.models.sources, sim_node.core.cameras, '
            'sim_node.core.lidar, sim_node.session, sim_node.simulation; '
            'bad = [m for m in sys.modules if m.split(".")[0] in '
            '("rclpy", "geometry_msgs", "std_msgs", "simulation_interfaces", "tf2_msgs")]; '
            'print(bad); sys.exit(1 if bad else 0)')
    out = subprocess.run([sys.executable, '-c', code], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr


#: rosdep keys of the Python packages the code imports (ROS packages are their own keys).
ROSDEP_KEYS = {'numpy': 'python3-numpy', 'mujoco': 'python3-mujoco-pip',
               'trimesh': 'python3-trimesh-pip', 'gymnasium': 'python3-gymnasium-pip',
               'regex': 'python3-regex', 'defusedxml': 'python3-defusedxml', 'PIL': 'python3-pil',
               'collada': 'python3-collada', 'yaml': 'python3-yaml'}
#: Imported, but rosdep has no key: ros_env/requirements.txt installs them, package.xml says
#: so in a comment, and the code says what to pip install when one is missing.
PIP_ONLY = {'fast_simplification', 'coacd', 'rosbags', 'mcap', 'viser', 'glfw'}


def test_package_xml_declares_exactly_what_the_code_imports():
    import ast
    import xml.etree.ElementTree as ET
    imported = set()
    for folder in ('sim_node', 'msg_adapters', 'launch'):
        for f in (ROOT / folder).rglob('*.py'):
            for node in ast.walk(ast.parse(f.read_text())):
                if isinstance(node, ast.Import):
                    imported |= {a.name.split('.')[0] for a in node.names}
                elif isinstance(node, ast.ImportFrom) and node.level == 0:
                    imported.add(node.module.split('.')[0])
    assert 'launch_ros' in imported
    own = {f.stem for folder in ('sim_node', 'msg_adapters')
           for f in (ROOT / folder).rglob('*.py')}
    third_party = {m for m in imported - set(sys.stdlib_module_names) - own - PIP_ONLY
                   if m not in ('sim_node', 'msg_adapters')}
    # The launch file runs rviz2; MuJoCo's headless GL contexts import PyOpenGL.
    wanted = {ROSDEP_KEYS.get(m, m) for m in third_party} | {'rviz2', 'python3-opengl'}
    root = ET.parse(ROOT / 'package.xml').getroot()
    declared = {e.text for e in root.iter('exec_depend')}
    assert declared == wanted, (f'undeclared: {sorted(wanted - declared)}, '
                                f'declared but not imported: {sorted(declared - wanted)}')


def test_mujoco_is_a_release_with_a_sound_sparse_factorization():
    """
    The bindings are MuJoCo 4.0.1 or later: 4.0.0's sparse Cholesky gave Newton a wrong factor.

    The project's requirements install mujoco-core 4.0.1 without the 4.0.0 metapackage that
    pinned the broken release (MuJoCo issue 3767); the viewer's GLFW comes along.
    """
    import importlib.metadata

    import mujoco
    version = tuple(int(x) for x in mujoco.mj_versionString().split('.')[:3])
    assert version >= (4, 0, 1), mujoco.mj_versionString()
    assert importlib.metadata.version('glfw')


def _stacked_humanoids(n: int):
    """Gymnasium's humanoid `n` times, dropped on each other: branched trees in contact."""
    import os

    import gymnasium
    import mujoco
    path = os.path.join(os.path.dirname(gymnasium.__file__), 'envs', 'mujoco', 'assets',
                        'humanoid.xml')
    spec = mujoco.MjSpec.from_file(path)
    for key in list(spec.keys):
        spec.delete(key)
    for i in range(1, n):
        other = mujoco.MjSpec.from_file(path)
        for key in list(other.keys):
            other.delete(key)
        frame = spec.worldbody.add_frame(pos=[0.2 * i, 0.1 * i, 0.9 * i],
                                         quat=[0.9, 0.3, 0.2, 0.1])
        frame.attach_body(other.body('torso'), f'h{i}_', '')
    return spec.compile()


def test_the_sparse_and_dense_jacobian_paths_agree_on_branched_trees_in_contact():
    """
    Newton steps the same with MuJoCo's sparse and dense constraint Jacobians.

    Four humanoids falling on each other for 1.2 s (92 dofs, up to ~120 constraints): on 4.0.0
    the two paths parted by 0.32 in qpos and the sparse one took more Newton iterations (its
    Hessian factor was wrong); on 4.0.1 they agree to 1e-10.
    """
    import mujoco
    import numpy as np
    runs = []
    for jacobian in (mujoco.mjtJacobian.mjJAC_SPARSE, mujoco.mjtJacobian.mjJAC_DENSE):
        model = _stacked_humanoids(4)
        model.opt.solver, model.opt.jacobian = mujoco.mjtSolver.mjSOL_NEWTON, jacobian
        data = mujoco.MjData(model)
        iterations = 0
        for _ in range(600):
            mujoco.mj_step(model, data)
            iterations += int(data.solver_niter[0])
        runs.append((data.qpos.copy(), iterations))
    (sparse, sparse_iterations), (dense, dense_iterations) = runs
    assert np.abs(sparse - dense).max() < 1e-6
    assert abs(sparse_iterations - dense_iterations) <= 0.01 * dense_iterations  # 4.0.0: 8%


def test_a_faulty_mujoco_release_is_named_with_what_to_install():
    """On a ROS machine pip may bring 4.0.0 anyway: the first world made says what to do."""
    from sim_node.core.stepping import guard
    note = guard.release_warning('4.0.0')
    assert 'issue 3767' in note and 'pip install "mujoco-core>=4.0.1"' in note
    assert guard.release_warning('4.0.1') == '' and guard.release_warning('3.3.7') == ''
