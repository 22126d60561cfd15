#!/usr/bin/env python3
"""
Set up everything `sim` needs to run and test, then write `.build/env.sh`.

Two cases:

* A ROS 2 Jazzy installation is sourced (``ROS_DISTRO=jazzy`` and its Python packages import):
  it is used as it is; only the `sim` package is built with colcon.
* No ROS: a project-local venv (``.venv``) gets rclpy and common_interfaces from the package
  index, plus mujoco, numpy, trimesh, gymnasium, pytest and colcon. ``tf2_msgs``,
  ``simulation_interfaces``, ``control_msgs``, ``controller_manager_msgs`` and
  ``ros_gz_interfaces`` (its contact messages) are built from the definitions in
  ``ros_env/interfaces`` (about six minutes the first time) and cached under
  ``.build/interfaces``; they are rebuilt only when those definitions or the requirements
  change.

Every step is skipped when its inputs have not changed, so a warm run takes seconds.
Run with the system's python3: ``python3 ros_env/bootstrap.py``.
"""

import hashlib
import os
from pathlib import Path
import shutil
import subprocess
import sys
import time

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / '.venv'
BUILD = ROOT / '.build'
INTERFACES_SRC = ROOT / 'ros_env' / 'interfaces'
REQUIREMENTS = ROOT / 'ros_env' / 'requirements.txt'
ENV_FILE = BUILD / 'env.sh'
# What goes into the `sim` package build; a change to any of these rebuilds it.
SIM_SOURCES = ('package.xml', 'setup.py', 'setup.cfg', 'resource', 'sim_node', 'msg_adapters',
               'scenes', 'launch', 'rviz')
# The wheels' CMake exports name the wheel build machine's interpreter paths.
WHEEL_PYTHON_INCLUDE = '/opt/python/cp311-cp311/include/python3.11'
WHEEL_NUMPY_INCLUDE = '/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include'

_t0 = time.monotonic()


def say(msg: str) -> None:
    print(f'[setup {time.monotonic() - _t0:6.1f}s] {msg}', flush=True)


def run(cmd: list, **kw) -> None:
    try:
        subprocess.run(cmd, check=True, **kw)
    except subprocess.CalledProcessError as exc:
        sys.exit(f'[setup] FAILED: {" ".join(map(str, cmd))} (exit {exc.returncode}).\n'
                 f'[setup] Fix the error above and run the same command again; finished steps '
                 f'are cached. To start over: rm -rf .venv .build')


def digest(*paths: Path, extra: str = '') -> str:
    h = hashlib.sha256(extra.encode())
    for base in paths:
        files = [base] if base.is_file() else sorted(p for p in base.rglob('*') if p.is_file())
        for f in files:
            if '__pycache__' in f.parts or f.suffix == '.pyc':
                continue
            h.update(str(f.relative_to(ROOT)).encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def stamp_ok(stamp: Path, key: str) -> bool:
    return stamp.is_file() and stamp.read_text() == key


def system_ros_sourced() -> bool:
    if os.environ.get('ROS_DISTRO') != 'jazzy':
        return False
    probe = ('import rclpy, tf2_msgs.msg, simulation_interfaces.srv, '
             'control_msgs.action, controller_manager_msgs.srv, ros_gz_interfaces.msg')
    ok = subprocess.run(['python3', '-c', probe], capture_output=True).returncode == 0
    if not ok:
        sys.exit('[setup] ROS 2 Jazzy is sourced but tf2_msgs, simulation_interfaces, '
                 'control_msgs, controller_manager_msgs or ros_gz_interfaces is missing. Run: '
                 'rosdep install --from-paths . -y --ignore-src')
    return True


def ensure_venv() -> Path:
    python = VENV / 'bin' / 'python'
    stamp = VENV / '.requirements.sha256'
    key = digest(REQUIREMENTS, extra=sys.version)
    if python.exists() and stamp_ok(stamp, key):
        say('venv is up to date (.venv)')
        return python
    if not python.exists():
        say('creating the project venv (.venv)')
        run([sys.executable, '-m', 'venv', str(VENV)])
    say('installing rclpy, common_interfaces, the rosidl toolchain, mujoco, numpy, trimesh, '
        'gymnasium, PyOpenGL, Pillow, pytest, colcon from the package index (about 30 s)')
    # The ROS wheels re-exec the interpreter; the guard keeps pip's own process plain.
    run([str(python), '-m', 'pip', 'install', '--quiet', '--upgrade', 'pip'])
    drop_mujoco_metapackage(python)
    run([str(python), '-m', 'pip', 'install', '--quiet', '-r', str(REQUIREMENTS)])
    patch_wheel_cmake_exports(python)
    stamp.write_text(key)
    return python


def drop_mujoco_metapackage(python: Path) -> None:
    """
    Take away the `mujoco` metapackage (and mujoco-studio) a venv made before 4.0.1 holds.

    It pins mujoco-core==4.0.0, the release whose sparse factorization 4.0.1 mends (see
    requirements.txt). Both ship ``mujoco/__init__.py`` with mujoco-core, so uninstalling them
    takes that file away too: mujoco-core is installed again over it.
    """
    check = [str(python), '-c', 'import importlib.metadata as m; m.version("mujoco")']
    if subprocess.run(check, capture_output=True).returncode != 0:
        return  # a fresh venv, or one already without it
    say('replacing the mujoco 4.0.0 metapackage by mujoco-core 4.0.1 (a fix of its solver)')
    run([str(python), '-m', 'pip', 'uninstall', '--quiet', '--yes', 'mujoco', 'mujoco-studio'])
    run([str(python), '-m', 'pip', 'install', '--quiet', '--force-reinstall', '--no-deps',
         'mujoco-core>=4.0.1,<4.1'])


def patch_wheel_cmake_exports(python: Path) -> None:
    """Point the wheels' CMake exports at this machine's interpreter and numpy headers."""
    probe = ('import sysconfig, numpy; print(sysconfig.get_paths()["include"]); '
             'print(numpy.get_include())')
    out = subprocess.run([str(python), '-c', probe], capture_output=True, text=True, check=True,
                         env={**os.environ, '_ROS_WHEELS_BOOTSTRAP_COMPLETE': '1'})
    py_include, np_include = out.stdout.split()
    patched = 0
    for f in (VENV / 'share').rglob('*.cmake'):
        text = f.read_text(errors='surrogateescape')
        if WHEEL_PYTHON_INCLUDE in text or WHEEL_NUMPY_INCLUDE in text:
            text = text.replace(WHEEL_NUMPY_INCLUDE, np_include)
            text = text.replace(WHEEL_PYTHON_INCLUDE, py_include)
            f.write_text(text, errors='surrogateescape')
            patched += 1
    say(f'patched {patched} CMake export files for this interpreter')


def venv_env(python: Path) -> dict:
    env = dict(os.environ)
    env['PATH'] = f'{VENV / "bin"}{os.pathsep}{env.get("PATH", "")}'
    env['VIRTUAL_ENV'] = str(VENV)
    env['AMENT_PREFIX_PATH'] = str(VENV)
    env['CMAKE_PREFIX_PATH'] = str(VENV)
    env['PYTHONPATH'] = ''
    return env


def ensure_interfaces(python: Path) -> Path:
    """Build the interface packages of ros_env/interfaces with colcon; cached."""
    ws = BUILD / 'interfaces'
    install = ws / 'install'
    stamp = ws / '.stamp'
    key = digest(INTERFACES_SRC, REQUIREMENTS, extra=sys.version)
    if stamp_ok(stamp, key):
        say('the interface packages are up to date (.build/interfaces)')
        return install
    say('building tf2_msgs, simulation_interfaces, control_msgs, controller_manager_msgs and '
        'ros_gz_interfaces from ros_env/interfaces with colcon (about six minutes on 2 cores, '
        'once; colcon prints each package as it starts and finishes)')
    shutil.rmtree(ws, ignore_errors=True)
    # The definitions live under a COLCON_IGNORE so that a workspace on a real ROS machine
    # never builds them; copy them out to build here.
    shutil.copytree(INTERFACES_SRC, ws / 'src')
    env = venv_env(python)
    run([str(VENV / 'bin' / 'colcon'), '--log-base', str(ws / 'log'), 'build',
         '--base-paths', str(ws / 'src'), '--build-base', str(ws / 'build'),
         '--install-base', str(install), '--merge-install',
         '--event-handlers', 'console_start_end+', 'status-',
         '--cmake-args', '-DBUILD_TESTING=OFF', f'-DPython3_EXECUTABLE={python}'],
        env=env, cwd=ws)
    shutil.rmtree(ws / 'build', ignore_errors=True)
    stamp.write_text(key)
    return install


def ensure_sim_package(colcon: str, env: dict) -> Path:
    ws = BUILD / 'sim_ws'
    install = ws / 'install'
    stamp = ws / '.stamp'
    key = digest(*(ROOT / s for s in SIM_SOURCES), extra=colcon)
    if stamp_ok(stamp, key):
        say('the sim package is up to date (.build/sim_ws)')
        return install
    say('building the sim package with colcon')
    shutil.rmtree(ws, ignore_errors=True)
    ws.mkdir(parents=True)
    run([colcon, '--log-base', str(ws / 'log'), 'build', '--base-paths', str(ROOT),
         '--packages-select', 'sim', '--build-base', str(ws / 'build'),
         '--install-base', str(install), '--merge-install',
         '--event-handlers', 'console_stderr-'], env=env, cwd=ws, stdout=subprocess.DEVNULL)
    stamp.write_text(key)
    return install


def write_gym_autoload(python: Path) -> None:
    """
    Gymnasium 1.x dropped entry-point plugins: a .pth line registers the sim/...

    ids (see sim_node/gym/autoload.py). It does nothing where sim_node is not importable.
    """
    site = subprocess.run([str(python), '-c', 'import sysconfig; print(sysconfig.get_paths()'
                           '["purelib"])'], capture_output=True, text=True, check=True,
                          env={**os.environ, '_ROS_WHEELS_BOOTSTRAP_COMPLETE': '1'}).stdout
    pth = Path(site.strip()) / 'sim_gym_autoload.pth'
    # Loaded by file path under its own name, so the sim_node package itself is not imported
    # at start-up (that would pin sys.modules['sim_node'] to the installed copy).
    line = ('import importlib.util as _u, sys as _y; _s = _u.find_spec("sim_node"); '
            '_p = _s and _u.spec_from_file_location("_sim_gym_autoload", '
            '_s.submodule_search_locations[0] + "/gym/autoload.py"); '
            '_m = _p and _u.module_from_spec(_p); '
            '_m and (_y.modules.__setitem__("_sim_gym_autoload", _m) or _p.loader.exec_module(_m))'
            '\n')
    if not pth.is_file() or pth.read_text() != line:
        pth.write_text(line)


#: Debian packages of a headless OpenGL driver for the cameras: Mesa's EGL (software rendering
#: through llvmpipe, no display or GPU needed).
GL_PACKAGES = ['libegl1', 'libegl-mesa0', 'libgl1-mesa-dri']
#: A virtual display for the viewer window's tests (and for a viewer on a machine without one).
DISPLAY_PACKAGES = ['xvfb', 'libgl1', 'libglx-mesa0', 'libxrandr2', 'libxinerama1', 'libxcursor1',
                    'libxi6', 'xdotool']


def ensure_headless_gl() -> None:
    """Cameras render through libEGL (or libOSMesa): install Mesa's EGL if neither is here."""
    import ctypes.util
    if ctypes.util.find_library('EGL') or ctypes.util.find_library('OSMesa'):
        say('headless OpenGL: present (libEGL or libOSMesa)')
        return
    if not apt_install(GL_PACKAGES, 'headless OpenGL for the cameras'):
        say('WARNING: no libEGL or libOSMesa: cameras will be off. Install them with: '
            f'sudo apt-get install {" ".join(GL_PACKAGES)}')


def ensure_virtual_display() -> None:
    """Install Xvfb where we may, for the viewer window's tests (else they skip)."""
    if shutil.which('Xvfb'):
        say('virtual display (Xvfb): present')
        return
    if not apt_install(DISPLAY_PACKAGES, "a virtual display for the viewer window's tests"):
        say('note: no Xvfb: the viewer window tests will skip. Install it with: '
            f'sudo apt-get install {" ".join(DISPLAY_PACKAGES)}')


#: A browser for the browser view's tests (headless, WebGL in software).
BROWSER_PACKAGES = ['chromium']


def ensure_browser() -> None:
    """Install Chromium for the browser view's tests in CI (a large package: only on ask)."""
    if shutil.which('chromium') or shutil.which('chromium-browser'):
        say('headless browser (chromium): present')
        return
    if os.environ.get('CI') or os.environ.get('SIM_INSTALL_BROWSER'):
        if apt_install(BROWSER_PACKAGES, "a headless browser for the browser view's tests"):
            return
    say("note: no chromium: the browser view's tests will skip. Install it with: sudo "
        'apt-get install chromium (or SIM_INSTALL_BROWSER=1 make setup as root)')


def apt_install(packages: list, why: str) -> bool:
    """Install Debian packages when running as root with apt; True when they installed."""
    if os.geteuid() != 0 or not shutil.which('apt-get'):
        return False
    say(f'installing {why} from Debian: {" ".join(packages)} (a minute or two)')
    apt_env = dict(os.environ, DEBIAN_FRONTEND='noninteractive')
    command = ['apt-get', 'install', '-y', '-q', '--no-install-recommends', *packages]
    if subprocess.run(command, env=apt_env).returncode == 0:
        return True
    subprocess.run(['apt-get', 'update', '-q'], env=apt_env)  # lists missing on a new machine
    return subprocess.run(command, env=apt_env).returncode == 0


def write_env_file(lines: list) -> None:
    ENV_FILE.write_text('# Generated by ros_env/bootstrap.py; source it from sh or bash.\n'
                        + '\n'.join(lines) + '\n')


def main() -> None:
    BUILD.mkdir(exist_ok=True)
    (BUILD / 'COLCON_IGNORE').touch()
    ensure_headless_gl()
    ensure_virtual_display()
    ensure_browser()
    pyver = f'python{sys.version_info.major}.{sys.version_info.minor}'
    if system_ros_sourced():
        say('using the sourced ROS 2 Jazzy installation (no venv)')
        sim_install = ensure_sim_package('colcon', dict(os.environ))
        write_env_file([
            f'export SIM_PREFIX="{sim_install}"',
            'export SIM_PYTHON=python3',
            f'export AMENT_PREFIX_PATH="{sim_install}:$AMENT_PREFIX_PATH"',
            f'export PYTHONPATH="{sim_install}/lib/{pyver}/site-packages:$PYTHONPATH"',
        ])
    else:
        say('no ROS 2 Jazzy sourced: using a project-local environment')
        python = ensure_venv()
        (VENV / 'COLCON_IGNORE').touch()
        iface = ensure_interfaces(python)
        env = venv_env(python)
        env['AMENT_PREFIX_PATH'] = f'{iface}{os.pathsep}{VENV}'
        sim_install = ensure_sim_package(str(VENV / 'bin' / 'colcon'), env)
        write_gym_autoload(python)
        write_env_file([
            f'export VIRTUAL_ENV="{VENV}"',
            f'export PATH="{VENV}/bin:$PATH"',
            f'export SIM_PREFIX="{sim_install}"',
            f'export SIM_PYTHON="{python}"',
            f'export AMENT_PREFIX_PATH="{sim_install}:{iface}:{VENV}"',
            f'export LD_LIBRARY_PATH="{iface}/lib:{VENV}/lib'
            '${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"',
            f'export PYTHONPATH="{sim_install}/lib/{pyver}/site-packages:'
            f'{iface}/lib/{pyver}/site-packages"',
        ])
    say(f'ready: {ENV_FILE.relative_to(ROOT)}')


if __name__ == '__main__':
    main()
