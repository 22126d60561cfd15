"""
The node's locks, watched while its listeners and controllers work (issue 51, item 5).

The node runs under ``lock_watch.py``: every lock of the ROS layer and of the controllers' laws
records which watched locks its taker held, and every ``World`` method records a call made with
one held. A session of the parts that take locks (spawns and deletes with robot descriptions
and controller managers, a diff drive driven and its odometry read, a gripper's goal, joint
commands, a reset, pause and play) must show no node lock held while calling the world, and
only the nestings docs/threading.md's lock order allows.
"""

import json
from pathlib import Path
import subprocess
import sys
import time

import controllers_corpus as corpus
import pytest

HERE = Path(__file__).resolve().parent
WATCH = (sys.executable, str(HERE / 'lock_watch.py'))

#: The nestings of node locks docs/threading.md allows (outer, inner): syncs of the controller
#: managers take turns on their sync lock, and inside it take the robots' lock briefly.
ALLOWED = {('controller_manager._sync_lock', 'controller_manager._lock')}
#: Leaves: taken inside any lock, and no lock is taken inside them (a controller's law's).
LEAVES = {'laws.lock'}


def _entries(path: Path) -> list:
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def test_the_watch_sees_a_world_call_under_a_node_lock_and_a_nesting(tmp_path):
    """The check itself: a planted world call under a watched lock, and a nesting, are seen."""
    report = tmp_path / 'planted.jsonl'
    script = f"""
import sys
sys.path.insert(0, {str(HERE)!r})
import lock_watch
lock_watch.install()
from sim_node.ros.control import controller_manager as cm
from sim_node.core.world import World
world = World.from_string('<mujoco/>')
outer = cm.threading.Lock()
inner = cm.threading.Lock()
with outer:
    with inner:
        world.clock()
world.clock()
"""
    env = dict(__import__('os').environ, SIM_LOCK_REPORT=str(report))
    done = subprocess.run([sys.executable, '-c', script], env=env, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    entries = _entries(report)
    calls = [e for e in entries if 'world' in e]
    assert len(calls) == 1 and calls[0]['world'] == 'the world lock'
    assert len(calls[0]['held']) == 2
    assert len([e for e in entries if 'pair' in e]) == 1


@pytest.mark.slow
def test_no_node_lock_is_held_while_calling_the_world_and_locks_nest_in_order(
        start_node, rclpy_context, tmp_path, monkeypatch):
    from conftest import action_client, wait_for, Watcher
    from control_msgs.action import GripperCommand
    from geometry_msgs.msg import TwistStamped
    from nav_msgs.msg import Odometry
    from sim_node.ros.client import SimClient
    from std_msgs.msg import Float64MultiArray
    report = tmp_path / 'locks.jsonl'
    monkeypatch.setenv('SIM_LOCK_REPORT', str(report))
    node = start_node(f'resource_paths:=["{tmp_path}"]', program=WATCH)
    sim = SimClient(timeout_sec=60)
    watch = Watcher()
    try:
        sim.entities()
        rover = corpus.write(tmp_path, 'rover.yaml', corpus.DIFF_DRIVE_YAML)
        sim.spawn('rover', resource_string=corpus.diff_drive(rover), position=(2.0, -2.0, 0.15))
        for name in ('joint_state_broadcaster', 'diff_drive_base_controller'):
            assert corpus.spawner(sim, name)[0] is None
        odoms = []
        watch.node.create_subscription(Odometry, '/diff_drive_base_controller/odom',
                                       odoms.append, 10)
        pub = watch.node.create_publisher(TwistStamped, '/diff_drive_base_controller/cmd_vel',
                                          10)
        cmd = TwistStamped()
        cmd.twist.linear.x = 0.3
        t0 = time.monotonic()
        while time.monotonic() - t0 < 2.0:
            pub.publish(cmd)
            time.sleep(0.05)
        wait_for(lambda: odoms and odoms[-1].pose.pose.position.x > 0.1, timeout=10)
        cart = corpus.write(tmp_path, 'cart.yaml', corpus.cart_yaml('position'))
        sim.spawn('cart', resource_string=corpus.cart('position', cart), namespace='second',
                  position=(0.0, 3.0, 0.0))
        manager = '/second/controller_manager'
        assert corpus.spawner(sim, 'forward_position_controller', manager=manager)[0] is None
        commands = watch.node.create_publisher(
            Float64MultiArray, '/second/forward_position_controller/commands', 10)
        for _ in range(5):
            commands.publish(Float64MultiArray(data=[0.2]))
            time.sleep(0.05)
        gripper = corpus.write(tmp_path, 'gripper.yaml', corpus.GRIPPER_YAML)
        sim.spawn('gripper', resource_string=corpus.gripper(gripper), namespace='third',
                  position=(-2.0, 2.0, 0.0))
        assert corpus.spawner(sim, 'gripper_controller',
                              manager='/third/controller_manager')[0] is None
        client = action_client(watch.node, GripperCommand, '/third/gripper_controller/gripper_cmd')
        assert client.wait_for_server(timeout_sec=10)
        goal = GripperCommand.Goal()
        goal.command.position = 0.03
        sent = client.send_goal_async(goal)
        wait_for(sent.done, timeout=20)
        result = sent.result().get_result_async()
        wait_for(result.done, timeout=30)
        assert result.result().result.reached_goal
        client.destroy()
        sim.pause()
        sim.step(10)
        sim.play()
        sim.reset()  # the spawned go, their managers with them
        sim.spawn('rover', resource_string=corpus.diff_drive(rover), position=(2.0, -2.0, 0.15))
        assert corpus.spawner(sim, 'diff_drive_base_controller')[0] is None
        sim.delete('rover')
    finally:
        watch.close()
        sim.close()
    code, _ = node.interrupt(timeout=10)
    assert code == 0, node.output()
    entries = _entries(report)
    calls = [f"{e['world']} with {e['held']} on {e['thread']}:\n{''.join(e['stack'])}"
             for e in entries if 'world' in e]
    assert calls == [], '\n'.join(calls)
    pairs = {tuple(e['pair']): ''.join(e['stack']) for e in entries if 'pair' in e}
    wrong = {p: s for p, s in pairs.items()
             if p not in ALLOWED and not (p[1] in LEAVES and p[0] not in LEAVES)}
    assert wrong == {}, wrong
    assert ('controller_manager._sync_lock', 'controller_manager._lock') in pairs  # watched
