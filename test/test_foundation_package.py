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
PIP_ONLY = {'fast_simplification', 'rosbags', 'mcap', 'viser', 'glfw'}


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
