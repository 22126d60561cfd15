"""
Run a launch file where ros2launch is not installed: ``run.py <file> [name:=value ...]``.

Declares its arguments, expands its OpaqueFunctions and starts each Node as ``ros2 launch``
would: ``sim`` executables from ``$SIM_PREFIX/lib/sim``, robot_state_publisher as the
stand-in beside this file; parameters through a parameters file, arguments as given. Waits for
the nodes that end by themselves (``sim spawn``), prints their output, stops the others, and
exits with the first non-zero exit status, else 0.
"""

import importlib.util
import os
from pathlib import Path
import subprocess
import sys
import tempfile

import yaml

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
LONG_RUNNING = {'robot_state_publisher'}


def load(path: str):
    spec = importlib.util.spec_from_file_location('launch_file', path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.generate_launch_description()


def command(node) -> list:
    if node.package == 'sim':
        exe = [str(Path(os.environ['SIM_PREFIX']) / 'lib' / 'sim' / node.executable)]
    elif node.executable == 'robot_state_publisher':
        exe = [sys.executable, str(HERE / 'robot_state_publisher.py')]
    else:
        raise SystemExit(f'the launch shim cannot start {node.package}/{node.executable}')
    args = [str(a) for a in node.arguments]
    if node.parameters:
        params = {}
        for p in node.parameters:
            params.update(p)
        f = tempfile.NamedTemporaryFile('w', suffix='.yaml', delete=False)
        yaml.safe_dump({'/**': {'ros__parameters': params}}, f)
        f.close()
        args += ['--ros-args', '--params-file', f.name]
    return exe + args


def main(argv: list) -> int:
    from launch.actions import DeclareLaunchArgument, OpaqueFunction
    from launch_ros.actions import Node
    description = load(argv[0])
    context = dict(a.split(':=', 1) for a in argv[1:])
    nodes = []
    for entity in description.entities:
        if isinstance(entity, DeclareLaunchArgument):
            context.setdefault(entity.name, entity.default_value)
        elif isinstance(entity, OpaqueFunction):
            nodes += [n for n in entity.function(context) if isinstance(n, Node)]
        elif isinstance(entity, Node):
            nodes.append(entity)
    procs = [(n, subprocess.Popen(command(n))) for n in nodes]
    status = 0
    for node, proc in procs:
        if node.executable not in LONG_RUNNING:
            code = proc.wait(120)
            status = status or code
    for node, proc in procs:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(10)
    return status


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
