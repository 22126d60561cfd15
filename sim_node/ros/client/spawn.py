"""
``ros2 run sim spawn``: bring a robot into the running simulation, as Gazebo's ``create`` does.

One of ``-topic <robot_description topic>`` (what robot_state_publisher publishes, transient
local: a late subscriber gets it), ``-file <path>`` (URDF, xacro, MJCF or SDF: a Gazebo
model's ``model.sdf``) or ``-string <URDF, MJCF or SDF text>``; then
``-name``, ``-x -y -z`` (m), ``-R -P -Y`` (rad), ``-namespace`` (the entity's ROS namespace),
``-allow_renaming``, ``-sim <namespace of the simulator's services>`` and ``-timeout`` (s, for
the topic and the services). It calls the standard SpawnEntity service and exits 0 on success;
otherwise it prints the standard's result code and message and exits with the code (1 when
there is none: no answer; 2: a bad argument; 130: Ctrl-C, with one line)::

    ros2 run sim spawn -topic robot_description -name cart -z 0.2
    ros2 run sim spawn -file ~/ws/src/cart_description/urdf/cart.urdf -name cart -Y 1.57
"""

import argparse
import os
from pathlib import Path
import re
import sys
from typing import Optional, Sequence

from ...core.base import quat

EXIT_FAILED = 1
#: Ctrl-C (SIGINT): one line, as a shell reports 128 + 2.
EXIT_INTERRUPTED = 130


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog='ros2 run sim spawn', description=__doc__.split('\n')[1],
                                prefix_chars='-', allow_abbrev=False)
    source = p.add_mutually_exclusive_group(required=True)
    source.add_argument('-topic', help='a topic with the robot description (std_msgs/String)')
    source.add_argument('-file', help='a URDF, xacro, MJCF or SDF file the simulator may read')
    source.add_argument('-string', help='the description itself (URDF, MJCF or SDF text)')
    p.add_argument('-name', default='', help='the entity name (default: the robot name)')
    for axis in ('x', 'y', 'z', 'R', 'P', 'Y'):
        p.add_argument(f'-{axis}', type=float, default=0.0)
    p.add_argument('-namespace', default='', help="the entity's ROS namespace")
    p.add_argument('-allow_renaming', action='store_true')
    p.add_argument('-sim', default='', help="the simulator's namespace (default: '/')")
    p.add_argument('-timeout', type=float, default=30.0,
                   help='seconds to wait for the description topic and the services')
    return p


def quaternion_xyzw(roll: float, pitch: float, yaw: float) -> tuple:
    """Return the quaternion (x, y, z, w) of fixed-axis roll, pitch, yaw (URDF's order)."""
    w, x, y, z = quat.from_rpy(roll, pitch, yaw)
    return float(x), float(y), float(z), float(w)


def _from_topic(node, topic: str, timeout: float) -> Optional[str]:
    """Return the first description published on `topic` (latched or not), or None."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String
    got = []
    qos = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                     reliability=ReliabilityPolicy.RELIABLE)
    sub = node.create_subscription(String, topic, lambda msg: got.append(msg.data), qos)
    # One executor for the whole wait: rclpy.spin_once makes one per call, and a Ctrl-C that
    # came while one was being made printed its half-made __del__'s traceback.
    from rclpy.executors import SingleThreadedExecutor
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    print(f'waiting for a robot description on {node.resolve_topic_name(topic)} '
          f'(up to {timeout:g} s, -timeout to change)', flush=True)
    try:
        deadline = node.get_clock().now().nanoseconds + int(timeout * 1e9)
        while not got and node.get_clock().now().nanoseconds < deadline:
            executor.spin_once(timeout_sec=0.1)
    finally:
        executor.remove_node(node)
        node.destroy_subscription(sub)
    return got[0] if got else None


def main(argv: Optional[Sequence[str]] = None) -> int:
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.utilities import remove_ros_args
    args = _parser().parse_args(remove_ros_args(list(sys.argv if argv is None
                                                     else ['spawn', *argv]))[1:])
    if not args.timeout > 0:
        _parser().error(f'-timeout must be a positive number of seconds, got {args.timeout:g}')
    rclpy.init(args=None if argv is None else ['spawn', *argv])
    node = rclpy.create_node('sim_spawn')
    interrupted = False
    try:
        return _spawn(node, args)
    except (KeyboardInterrupt, ExternalShutdownException):
        interrupted = True
        print('interrupted: nothing was spawned', file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        if interrupted:  # rclpy's SIGINT guard condition, collected at exit after a SIGINT,
            sys.stdout.flush()  # prints a traceback of its own (rclpy, Jazzy): nothing is
            sys.stderr.flush()  # left that needs an orderly exit
            os._exit(EXIT_INTERRUPTED)


def _say_decomposing(node) -> list:
    """
    Print what the simulator says on /diagnostics it is decomposing while the spawn waits.

    A concave collision mesh seen for the first time is split into convex parts before the
    spawn is answered (seconds, at most 30 s a mesh): the user is told why it takes a
    while. Returns the list of what was said, which the wait fills.
    """
    from diagnostic_msgs.msg import DiagnosticArray
    said: list = []

    def heard(msg) -> None:
        for status in msg.status:
            for kv in status.values:
                if kv.key != 'decomposing':
                    continue
                meshes = re.sub(r' \(\d+ s of at most [\d.]+\)', '', kv.value)
                if not said or said[-1] != meshes:
                    said.append(meshes)
                    print(f'the simulator is splitting concave collision meshes into convex '
                          f'parts (once: they are cached): {kv.value}', flush=True)
    node.create_subscription(DiagnosticArray, '/diagnostics', heard, 10)
    return said


def _spawn(node, args: argparse.Namespace) -> int:
    """Find the description, call the service, say what happened; return the exit status."""
    from .sim_client import SimClient, SimServiceError
    uri, text = '', ''
    if args.topic:
        text = _from_topic(node, args.topic, args.timeout)
        if text is None:
            print(f'nothing was published on {args.topic!r} within {args.timeout:g} s: '
                  'is robot_state_publisher (or another publisher of the description) '
                  'running, with that topic name?', file=sys.stderr)
            return EXIT_FAILED
    elif args.file:
        path = Path(args.file).expanduser().resolve()
        uri = path.as_uri()
    else:
        text = args.string
    sim = SimClient(namespace=args.sim, node=node, timeout_sec=args.timeout)
    busy = _say_decomposing(node)
    try:
        name = sim.spawn(args.name, uri=uri, resource_string=text,
                         position=(args.x, args.y, args.z),
                         orientation_xyzw=quaternion_xyzw(args.R, args.P, args.Y),
                         allow_renaming=args.allow_renaming or not args.name,
                         namespace=args.namespace)
    except SimServiceError as exc:
        print(f'spawn_entity answered {exc.code}: {exc.message}', file=sys.stderr)
        return exc.code if 0 < exc.code < 256 else EXIT_FAILED
    except TimeoutError as exc:
        if busy:
            print(f'{exc}: the simulator was still decomposing {busy[-1]}; the spawn goes on '
                  'there (check with: ros2 service call /get_entities '
                  'simulation_interfaces/srv/GetEntities), and the parts are cached for the '
                  'next time: give a larger -timeout', file=sys.stderr)
            return EXIT_FAILED
        print(f'{exc}; is the simulator running (ros2 run sim node)?', file=sys.stderr)
        return EXIT_FAILED
    print(f'spawned {name!r}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
