"""
Hostile clients over the wire: bursts, duplicates, bad resources, and a soak from 4 clients.

Every request gets an answer with its exact code, and afterwards the world is intact: the same
entities, finite states, time moving on, the node answering. ``SIM_SOAK_SECONDS`` sets the
soak's length (60 s by default; longer soaks for a release).
"""

import math
import os
from pathlib import Path
import random
import threading
import time

from conftest import returns, serve_node, wait_for, Watcher
import pytest
from sim_node.ros.client import SimClient, SimServiceError
from sim_node.ros.settings.qos import SERVICE_QOS
from simulation_interfaces.msg import Result, SimulationState
from simulation_interfaces.srv import SetEntityState, SpawnEntities, SpawnEntity

SCENE_ENTITIES = ['robot', 'table', 'box_a', 'box_b']
SOAK_SECONDS = float(os.environ.get('SIM_SOAK_SECONDS', '60'))


@pytest.fixture(scope='module')
def files(tmp_path_factory) -> Path:
    """Return a resource folder of the node's own, with a FIFO among a model's assets."""
    folder = tmp_path_factory.mktemp('resources')
    os.mkfifo(folder / 'face.png')
    (folder / 'fifo_texture.xml').write_text(
        '<mujoco><asset><texture name="t" type="cube" fileright="face.png"/>'
        '<material name="m" texture="t"/></asset><worldbody><body name="b"><freejoint/>'
        '<geom size=".05" material="m"/></body></worldbody></mujoco>')
    return folder


@pytest.fixture(scope='module')
def node(files):
    from conftest import installed_prefix
    scenes = installed_prefix() / 'share' / 'sim' / 'scenes'
    yield from serve_node(f"resource_paths:=['{scenes}', '{files}']")


def code_of(call) -> int:
    try:
        call()
        return Result.RESULT_OK
    except SimServiceError as exc:
        return exc.code


def assert_intact(sim: SimClient, extra: tuple = ()) -> None:
    assert sorted(sim.entities()) == sorted(SCENE_ENTITIES + list(extra))
    t0 = sim.entity_state('box_a')['stamp']
    for name in SCENE_ENTITIES:
        st = sim.entity_state(name)
        assert all(math.isfinite(v) for v in st['position'] + st['orientation_xyzw'])
    wait_for(lambda: sim.entity_state('box_a')['stamp'] > t0, timeout=5)  # time moves on


def burst(n: int, make_request) -> list:
    """N clients, each on its own node, all calling at once; returns their Result codes."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    nodes = [rclpy.create_node(f'burst_{i}_{id(make_request):x}') for i in range(n)]
    executor = SingleThreadedExecutor()  # spun by this thread only (see _spin_until)
    try:
        srv_type, service = make_request(None)
        # The clients keep a deep reply history, as SimClient does (see sim_node.ros.settings.qos).
        clients = [nd.create_client(srv_type, service, qos_profile=SERVICE_QOS) for nd in nodes]
        for c in clients:
            assert c.wait_for_service(timeout_sec=20)
        for nd in nodes:
            executor.add_node(nd)
        clients = _warm_up(executor, nodes, clients, srv_type, service)
        futures = [c.call_async(make_request(i)) for i, c in enumerate(clients)]
        _spin_until(executor, futures, 60)
        return [f.result().result.result if f.done() else None for f in futures]
    finally:
        executor.shutdown()
        for nd in nodes:
            nd.destroy_node()


def _spin_until(executor, futures: list, seconds: float) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and not all(f.done() for f in futures):
        executor.spin_once(timeout_sec=0.05)


def _warm_up(executor, nodes: list, clients: list, srv_type, service: str) -> list:
    """
    Have each client get one answer (to a harmless empty request) before the burst.

    A client's response reader may match the server a moment after wait_for_service says the
    service is there (a DDS race of every ROS 2 client, ros2cli's too, longer on busy cores):
    an answer sent before that is lost on the client's side. A client that got one answer
    will get the next. A client still unanswered after a round is made anew on its node (a
    new response reader, matched afresh): in fresh-clone runs with both cores busy, about half
    the clients went unanswered for the whole minute of warm-up (why is not known yet).

    :returns: the clients, each one that got an answer.
    """
    clients = list(clients)
    deadline = time.monotonic() + 60
    pending = list(range(len(clients)))
    while pending and time.monotonic() < deadline:
        futures = [(i, clients[i].call_async(srv_type.Request())) for i in pending]
        _spin_until(executor, [f for _, f in futures], 3)
        pending = [i for i, f in futures if not f.done()]
        for i in pending:
            nodes[i].destroy_client(clients[i])
            clients[i] = nodes[i].create_client(srv_type, service, qos_profile=SERVICE_QOS)
            clients[i].wait_for_service(timeout_sec=5)
    assert not pending, f'{len(pending)} clients never got an answer to a warm-up request'
    return clients


def spawn_request(name: str, i: int) -> SpawnEntity.Request:
    req = SpawnEntity.Request(name=name, uri='box')
    p = req.initial_pose.pose.position
    p.x, p.y, p.z = -2.5 + (i % 10) * 0.5, -2.5 + (i // 10) * 0.5, 1.5
    return req


def assert_burst_served(codes: list, served: bool) -> None:
    """
    Every request of a burst was served, and every client got its answer, OK.

    The node dropped 38 of 50 requests before its request queue was deepened; clients with
    ROS's default reply depth of 10 lost 9 to 14 answers of 50 with both cores busy (replies
    to the other clients pushed theirs out, see sim_node.ros.settings.qos).
    """
    assert served
    assert codes == [Result.RESULT_OK] * len(codes), codes


#: Clients calling at once; 100 with every core busy made clients with ROS's default reply
#: depth lose answers in most runs, 50 in a few.
BURST = 100


@pytest.fixture
def busy_cores():
    """Keep every core busy with other processes, as a loaded robot computer is."""
    import subprocess
    import sys
    hogs = [subprocess.Popen([sys.executable, '-c', 'while True: pass'])
            for _ in range(os.cpu_count() or 2)]
    yield
    for h in hogs:
        h.kill()
        h.wait()


def test_a_burst_of_fifty_clients_is_served_whole(sim, busy_cores):
    codes = burst(BURST, lambda i: (SpawnEntity, '/spawn_entity') if i is None
                  else spawn_request(f'burst_{i}', i))
    names = set(sim.entities())
    assert_burst_served(codes, all(f'burst_{i}' in names for i in range(BURST)))
    from simulation_interfaces.srv import DeleteEntity
    codes = burst(BURST, lambda i: (DeleteEntity, '/delete_entity') if i is None
                  else DeleteEntity.Request(entity=f'burst_{i}'))
    assert_burst_served(codes, not any(n.startswith('burst_') for n in sim.entities()))
    assert_intact(sim)


def test_concurrent_duplicate_names_give_one_entity_and_the_standard_code_to_the_rest(sim):
    codes = burst(10, lambda i: (SpawnEntity, '/spawn_entity') if i is None
                  else spawn_request('twin', i))
    assert sorted(codes) == [Result.RESULT_OK] + [SpawnEntity.Response.NAME_NOT_UNIQUE] * 9
    assert sim.entities().count('twin') == 1
    sim.delete('twin')
    assert_intact(sim)


def test_hostile_requests_get_their_codes_and_leave_the_world_intact(sim, files):
    box = ('<mujoco><worldbody><body name="b"><freejoint/><geom size=".05"/></body>'
           '</worldbody></mujoco>')
    cases = [
        (lambda: sim.spawn('x', resource_string='<!DOCTYPE m [<!ENTITY a "b">]>' + box),
         SpawnEntity.Response.RESOURCE_PARSE_ERROR),
        (lambda: sim.spawn('x', resource_string=box.replace(
            '<worldbody>', '<asset><texture name="t" type="cube" fileright="/etc/passwd"/>'
            '</asset><worldbody>')), SpawnEntity.Response.MISSING_ASSETS),
        (lambda: sim.spawn('x', uri=(files / 'fifo_texture.xml').as_uri()),
         SpawnEntity.Response.UNSUPPORTED_ASSETS),
        (lambda: sim.spawn('n' * 1_000_000, uri='box'), SpawnEntity.Response.NAME_INVALID),
        (lambda: sim.spawn('x', uri='box', position=(0, math.nan, 1)),
         SpawnEntity.Response.INVALID_POSE),
        (lambda: sim.spawn('x', uri='box', orientation_xyzw=(0, 0, 0, 0)),
         SpawnEntity.Response.INVALID_POSE),
        (lambda: sim.set_entity_state('box_a', (0, 0, math.inf)),
         SetEntityState.Response.INVALID_POSE),
        (lambda: sim.set_entity_state('no_such_entity', (0, 0, 1)), Result.RESULT_NOT_FOUND),
        (lambda: sim.delete('table'), Result.RESULT_INCORRECT_STATE),  # part of the scene
        (lambda: sim.reset(8), Result.RESULT_FEATURE_UNSUPPORTED),  # no such scope bit
        (lambda: sim.entities(pattern='(unclosed'), Result.RESULT_OPERATION_FAILED),
    ]
    got = returns(lambda: [code_of(call) for call, _ in cases])  # nothing blocks (the FIFO)
    assert got == [code for _, code in cases]
    assert_intact(sim)


def test_spawn_entities_answers_once_per_request_and_keeps_the_good_ones(sim):
    from simulation_interfaces.msg import SpawnEntity as SpawnItem
    items = []
    for i, (uri, name) in enumerate([('box', 'good_1'), ('nope_nope', 'bad'),
                                     ('box', 'good_2'), ('', 'empty')]):
        item = SpawnItem(name=name)
        item.entity_resource.uri = uri
        item.initial_pose.pose.position.x, item.initial_pose.pose.position.z = i * 0.5 - 1, 1.5
        items.append(item)
    response = sim.call('spawn_entities', SpawnEntities,
                        SpawnEntities.Request(spawn_requests=items), check=False)
    assert response.result.result == SpawnEntities.Response.ENTITIES_SPAWN_FAILED
    assert [r.result.result for r in response.results] == [
        Result.RESULT_OK, Result.RESULT_NOT_FOUND, Result.RESULT_OK,
        SpawnEntity.Response.NO_RESOURCE]
    assert {'good_1', 'good_2'} <= set(sim.entities())  # not atomic: the good ones stay
    sim.reset(4)
    assert_intact(sim)


def _rss_mib(pid: int) -> float:
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS'):
            return int(line.split()[1]) / 1024
    raise RuntimeError('no VmRSS')


def test_soak_four_clients_at_random_every_request_answered_memory_bounded(node, sim):
    """Random spawns, deletes, resets and steps from 4 clients for SIM_SOAK_SECONDS."""
    allowed = {Result.RESULT_OK, Result.RESULT_NOT_FOUND, Result.RESULT_INCORRECT_STATE,
               SpawnEntity.Response.NAME_NOT_UNIQUE}
    counts, unexpected, errors = [0] * 4, [], []
    watch = Watcher()
    before = _rss_mib(node.proc.pid)
    stop = time.monotonic() + SOAK_SECONDS

    def worker(k: int) -> None:
        rng = random.Random(k)
        try:
            c = SimClient(timeout_sec=30)
            try:
                while time.monotonic() < stop:
                    action = rng.choice(['spawn', 'spawn', 'delete', 'step', 'reset', 'state'])
                    name = f'soak_{k}_{rng.randrange(12)}'
                    if action == 'spawn':
                        x, y = rng.uniform(-2.5, 2.5), rng.uniform(-2.5, 2.5)
                        code = code_of(lambda: c.spawn(name, uri=rng.choice(['box', 'sphere']),
                                                       position=(x, y, 2.0)))
                        if code == SpawnEntity.Response.INVALID_POSE:
                            code = Result.RESULT_OK  # landed in another object: refused, fine
                    elif action == 'delete':
                        code = code_of(lambda: c.delete(name))
                    elif action == 'step':
                        code = code_of(lambda: c.step(5))  # only while paused
                        if code == Result.RESULT_OPERATION_FAILED:  # playing: the standard's 4
                            code = Result.RESULT_OK
                    elif action == 'reset':
                        code = code_of(lambda: c.reset(rng.choice([1, 4])))
                    else:
                        code = code_of(lambda: c.set_state(rng.choice(
                            [SimulationState.STATE_PAUSED, SimulationState.STATE_PLAYING])))
                        if code in (101,):  # ALREADY_IN_TARGET_STATE
                            code = Result.RESULT_OK
                    counts[k] += 1
                    if code not in allowed:
                        unexpected.append((action, code))
            finally:
                c.close()
        except Exception as exc:  # a request that never got its answer, above all
            errors.append(repr(exc))

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(SOAK_SECONDS + 120)
    try:
        assert not errors, errors
        assert not unexpected, unexpected[:10]
        assert min(counts) > 5, counts
        sim.reset()
        code_of(sim.play)
        grown = _rss_mib(node.proc.pid) - before
        assert grown < 150, f'node RSS grew {grown:.0f} MiB over {sum(counts)} requests'
        assert_intact(sim)
        bad = [k for k, (_, _, pos, _) in watch.tf.items()
               if not all(math.isfinite(v) for v in pos)]
        assert not bad, bad
    finally:
        watch.close()
