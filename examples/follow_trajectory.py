"""
A MoveIt-style client: spawn an arm from a model file, send it a trajectory, cancel another.

Against a running node (``make run ARGS="--ros-args -p resource_paths:=['<folder>']"``)::

    . .build/env.sh
    export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
    python examples/follow_trajectory.py file:///<folder>/robots/panda/robot.xml

It spawns the file as entity ``arm``, sends its first seven joints a three-point trajectory
over ``arm/follow_joint_trajectory`` (control_msgs/FollowJointTrajectory, as MoveIt's
trajectory execution does), prints the largest tracking error the feedback reported and the
result, then sends a second, slow trajectory and cancels it midway: the joints hold there.
"""

import sys
import time

from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTolerance
import rclpy
from rclpy.action import ActionClient
from sensor_msgs.msg import JointState
from sim_node.ros.client import SimClient
from sim_node.ros.commands.trajectories import duration
from trajectory_msgs.msg import JointTrajectoryPoint

ENTITY = 'arm'


def wait(future, node, seconds: float = 30.0):
    """Spin `node` until `future` is done; return its result."""
    rclpy.spin_until_future_complete(node, future, timeout_sec=seconds)
    if not future.done():
        raise TimeoutError(f'no answer within {seconds} s')
    return future.result()


def current_positions(node, joints: list) -> list:
    """Read the joints' positions from one joint_states message."""
    got = []
    sub = node.create_subscription(JointState, 'joint_states', got.append, 10)
    deadline = time.monotonic() + 10
    while not got or not set(joints) <= set(got[-1].name):
        rclpy.spin_once(node, timeout_sec=0.1)
        if time.monotonic() > deadline:
            raise TimeoutError("no joint_states with the arm's joints")
    node.destroy_subscription(sub)
    js = got[-1]
    return [js.position[list(js.name).index(j)] for j in joints]


def goal(joints: list, points: list, goal_tolerance: float = 0.0):
    g = FollowJointTrajectory.Goal()
    g.trajectory.joint_names = joints
    g.trajectory.points = [JointTrajectoryPoint(positions=list(q), time_from_start=duration(t))
                           for t, q in points]
    if goal_tolerance:
        g.goal_tolerance = [JointTolerance(name=j, position=goal_tolerance) for j in joints]
        g.goal_time_tolerance = duration(1.0)
    return g


def main(uri: str) -> dict:
    """Run the example; return what it printed, for the test."""
    node = rclpy.create_node('follow_trajectory_example')
    sim = SimClient(node=rclpy.create_node('follow_trajectory_example_client'))
    sim.spawn(ENTITY, uri=uri, position=(2.0, 2.0, 0.0))
    joints = arm_joints(node)
    client = ActionClient(node, FollowJointTrajectory, f'{ENTITY}/follow_joint_trajectory')
    client.wait_for_server(timeout_sec=30)
    q0 = current_positions(node, joints)
    offsets = [0.4, -0.3, 0.3, -0.4, 0.3, 0.4, -0.3][:len(joints)]
    points = [(t, [q + k * o for q, o in zip(q0, offsets)])
              for t, k in ((0.5, 0.5), (1.0, 1.0), (1.5, 0.5))]
    worst = [0.0]

    def on_feedback(msg):
        worst[0] = max([worst[0]] + [abs(e) for e in msg.feedback.error.positions])
    handle = wait(client.send_goal_async(goal(joints, points, 0.01), on_feedback), node)
    res = wait(handle.get_result_async(), node).result
    print(f'{len(joints)} joints, 3 points over 1.5 s: error_code {res.error_code}, largest '
          f'tracking error in the feedback {worst[0]:.4f} rad')
    # A slow one, canceled midway: the joints stay where they were then.
    far = [q + 2 * o for q, o in zip(q0, offsets)]  # inside the panda's joint ranges
    slow = wait(client.send_goal_async(goal(joints, [(6.0, far)])), node)
    end = time.monotonic() + 1.5
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)
    wait(slow.cancel_goal_async(), node)
    canceled = wait(slow.get_result_async(), node)
    held = current_positions(node, joints)
    print(f'second goal canceled midway (status {canceled.status}); joint 1 holds at '
          f'{held[0]:.3f} rad')
    sim.delete(ENTITY)
    client.destroy()
    sim.close()
    node.destroy_node()
    return {'joints': joints, 'error_code': res.error_code, 'worst_error': worst[0],
            'canceled_status': canceled.status, 'start': q0, 'held': held}


def arm_joints(node) -> list:
    """Return the arm's first seven joints, from joint_states once the spawned arm is on it."""
    got = []
    sub = node.create_subscription(JointState, 'joint_states', got.append, 10)
    deadline = time.monotonic() + 10
    while not got or not any(n.startswith(ENTITY + '/') for n in got[-1].name):
        rclpy.spin_once(node, timeout_sec=0.1)
        if time.monotonic() > deadline:
            raise TimeoutError('no joint_states with the arm: is the node running?')
    node.destroy_subscription(sub)
    return [n for n in got[-1].name if n.startswith(ENTITY + '/')][:7]


if __name__ == '__main__':
    rclpy.init()
    try:
        main(sys.argv[1])
    finally:
        rclpy.try_shutdown()
