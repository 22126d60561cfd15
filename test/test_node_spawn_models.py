"""
A user's own model file over the wire.

Gymnasium's ant spawned with spawn_entity from a file:// URI inside resource_paths, seen on /tf and
in markers, commanded, deleted.
"""

import os

from conftest import serve_node, wait_for, Watcher
import gymnasium
import pytest
from sim_node.ros.client import SimClient

GYM_ASSETS = os.path.join(os.path.dirname(gymnasium.__file__), 'envs', 'mujoco', 'assets')


@pytest.fixture(scope='module')
def node():
    yield from serve_node(f'resource_paths:=["{GYM_ASSETS}"]')


def test_spawn_a_gymnasium_ant_see_it_command_it_delete_it(node, rclpy_context):
    sim = SimClient(timeout_sec=30)
    watch = Watcher()
    try:
        name = sim.spawn('ant', uri=f'file://{GYM_ASSETS}/ant.xml', position=(2.5, 2.5, 1.0))
        assert name == 'ant' and 'ant' in sim.entities()
        # Moving bodies on /tf, welded ones (front_left_leg) on /tf_static.
        wait_for(lambda: all(f in watch.tf for f in ('ant', 'ant/aux_1', 'ant/body_0')),
                 timeout=10)
        wait_for(lambda: 'ant/front_left_leg' in watch.tf_static, timeout=10)
        assert watch.tf['ant'][1] == 'world'  # the torso's free joint: a child of the world
        wait_for(lambda: any(ns == 'sim/ant' for ns, _ in watch.markers), timeout=5)
        wait_for(lambda: watch.joint_states is not None
                 and 'ant/hip_1' in watch.joint_states.name, timeout=5)
        from sensor_msgs.msg import JointState
        pub = watch.node.create_publisher(JointState, 'joint_commands', 10)

        def hip_driven_out():  # its motor, by the prefixed joint name
            pub.publish(JointState(name=['ant/hip_1'], effort=[1.0]))
            js = watch.joint_states
            return js.position[list(js.name).index('ant/hip_1')] > 0.3  # range: +-30 deg
        wait_for(hip_driven_out, timeout=15, interval=0.2)
        sim.delete('ant')
        assert 'ant' not in sim.entities()
        wait_for(lambda: not any(ns == 'sim/ant' for ns, _ in watch.markers), timeout=5)
    finally:
        watch.close()
        sim.close()
