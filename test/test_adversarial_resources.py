"""
Hostile model files and text: MuJoCo never opens a file the node did not read and check.

Each case asserts the exact error type (the node maps it to the standard code), that it comes
at once (no FIFO blocks, no 11 s compile), and that the world is intact afterwards.
"""

import gc
import os
from pathlib import Path
import struct

from conftest import DEFAULT_SCENE, returns
import numpy as np
import pytest
from sim_node.core.base.memory import release_free_memory
from sim_node.core.config import WorldConfig
from sim_node.core.errors import (MissingAssetsError, NameInvalidError, ResourceParseError,
                                  UnsupportedAssetsError, UnsupportedFormatError)
from sim_node.core.models import assets, sources
from sim_node.core.world import World
import trimesh

BODY = '<worldbody><body name="b"><freejoint/><geom size=".05"/></body></worldbody>'


def cube_texture(**files) -> str:
    attrs = ' '.join(f'{k}="{v}"' for k, v in files.items())
    return (f'<mujoco><asset><texture name="t" type="cube" {attrs}/>'
            f'<material name="m" texture="t"/></asset>'
            f'<worldbody><body name="b"><freejoint/><geom size=".05" material="m"/></body>'
            f'</worldbody></mujoco>')


def png(path: Path, width: int = 4, height: int = 4) -> Path:
    from PIL import Image
    Image.new('RGB', (width, height), (200, 10, 10)).save(path)
    return path


def binary_stl(path: Path, n_faces: int) -> Path:
    tri = np.zeros((n_faces, 12), dtype='<f4')
    tri[:, 3:12] = np.tile([0, 0, 0, 0.01, 0, 0, 0, 0.01, 0], (n_faces, 1))
    rec = np.zeros(n_faces, dtype=[('f', '<f4', 12), ('a', '<u2')])
    rec['f'] = tri
    with open(path, 'wb') as f:
        f.write(b'\0' * 80 + struct.pack('<I', n_faces) + rec.tobytes())
    return path


@pytest.fixture
def world():
    return World.from_file(str(DEFAULT_SCENE))


def assert_intact(world: World, names: list) -> None:
    assert [e.name for e in world.entities()] == names
    world.step(5)
    assert np.isfinite(world.get_state().values).all()


def refused(call, error) -> str:
    """Return the message `call` is refused with (refused, not hung: see conftest.returns)."""
    with pytest.raises(error) as info:
        returns(call)
    return str(info.value)


@pytest.mark.parametrize('attr', ['fileright', 'fileleft', 'fileup', 'filedown', 'filefront',
                                  'fileback', 'file'])
def test_every_texture_file_attribute_is_checked_and_existence_does_not_leak(tmp_path, attr):
    roots = [str(tmp_path)]
    a = refused(lambda: sources.from_model_text(cube_texture(**{attr: '/etc/passwd'}),
                                                allowed_roots=roots), MissingAssetsError)
    b = refused(lambda: sources.from_model_text(cube_texture(**{attr: '/etc/no_such_file'}),
                                                allowed_roots=roots), MissingAssetsError)
    assert a.replace('passwd', 'X') == b.replace('no_such_file', 'X')  # same answer either way


def test_a_fifo_among_the_assets_is_refused_at_once(tmp_path, world):
    fifo = tmp_path / 'face.png'
    os.mkfifo(fifo)
    model = tmp_path / 'm.xml'
    model.write_text(cube_texture(fileright='face.png'))
    names = [e.name for e in world.entities()]
    refused(lambda: sources.from_file(str(model), allowed_roots=[str(tmp_path)]),
            UnsupportedAssetsError)
    include = tmp_path / 'inc.xml'
    include.write_text('<mujoco><include file="face.png"/>' + BODY + '</mujoco>')
    refused(lambda: sources.from_file(str(include), allowed_roots=[str(tmp_path)]),
            UnsupportedAssetsError)
    assert_intact(world, names)


def test_links_and_dot_dots_are_judged_by_where_they_really_lead(tmp_path, world):
    from sim_node.core.models.paths import real_path
    root, outside = tmp_path / 'root', tmp_path / 'outside'
    root.mkdir()
    outside.mkdir()
    box = trimesh.creation.box((0.1, 0.1, 0.1)).export(file_type='stl')  # binary STL
    (outside / 'secret.stl').write_bytes(box)
    (root / 'part.stl').write_bytes(box)
    (root / 'away.stl').symlink_to(outside / 'secret.stl')  # a link out of the root
    (root / 'here.stl').symlink_to(root / 'part.stl')  # a link within it
    (root / 'door').symlink_to(outside)  # a folder link out
    os.mkfifo(root / 'pipe')
    (root / 'loop').symlink_to(root / 'loop')
    roots = [str(root)]

    def mesh_model(name: str) -> str:
        return (f'<mujoco><asset><mesh name="m" file="{name}"/></asset><worldbody><body '
                f'name="b"><freejoint/><geom type="mesh" mesh="m"/></body></worldbody></mujoco>')

    names = [e.name for e in world.entities()]
    for escape in ('away.stl', 'door/secret.stl', '../outside/secret.stl',
                   str(root / 'door' / '..' / 'outside' / 'secret.stl')):
        (root / 'm.xml').write_text(mesh_model(escape))
        refused(lambda: sources.from_file(str(root / 'm.xml'), allowed_roots=roots),
                MissingAssetsError)
    (root / 'm.xml').write_text(mesh_model('here.stl'))
    world.spawn('linked', sources.from_file(str(root / 'm.xml'), allowed_roots=roots),
                position=(2, 2, 1))
    assert_intact(world, names + ['linked'])
    # the same answer as os.path.realpath, for existing paths and every other kind
    for path in (root / 'here.stl', root / 'away.stl', root / 'door' / 'secret.stl',
                 root / 'door' / '..' / 'part.stl', root / 'part.stl' / '..', root / 'pipe',
                 root / 'missing' / 'x.stl', root / 'loop', str(root) + '//part.stl', root):
        assert real_path(str(path)) == os.path.realpath(path), path


def test_includes_are_expanded_here_and_checked_like_any_file(tmp_path, world):
    (tmp_path / 'parts').mkdir()
    (tmp_path / 'parts' / 'body.xml').write_text(
        '<mujoco><worldbody><body name="inc"><freejoint/><geom size=".04"/></body>'
        '</worldbody></mujoco>')
    model = tmp_path / 'm.xml'
    model.write_text('<mujoco><include file="parts/body.xml"/></mujoco>')
    world.spawn('included', sources.from_file(str(model), allowed_roots=[str(tmp_path)]),
                position=[0, 1.5, 1])
    assert 'included' in [e.name for e in world.entities()]
    for target in ('/etc/passwd', '../outside.xml'):
        model.write_text(f'<mujoco><include file="{target}"/>{BODY}</mujoco>')
        refused(lambda: sources.from_file(str(model), allowed_roots=[str(tmp_path)]),
                MissingAssetsError)
    model.write_text('<mujoco><include file="m.xml"/></mujoco>')  # includes itself
    refused(lambda: sources.from_file(str(model), allowed_roots=[str(tmp_path)]),
            UnsupportedAssetsError)


@pytest.mark.parametrize('text', [
    '<!DOCTYPE mujoco [<!ENTITY a "aaaaaaaaaa">]><mujoco>' + BODY + '</mujoco>',
    '<!DOCTYPE mujoco SYSTEM "file:///etc/passwd"><mujoco>' + BODY + '</mujoco>',
    ('<?xml version="1.0"?><!DOCTYPE lolz [<!ENTITY lol "lol"><!ENTITY lol2 '
     '"&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">]><mujoco><worldbody><body name="&lol2;">'
     '<geom size=".1"/></body></worldbody></mujoco>'),
])
def test_doctype_and_entities_are_refused(text):
    message = refused(lambda: sources.from_model_text(text), ResourceParseError)
    assert 'DOCTYPE' in message or 'entit' in message


def test_a_5000_deep_urdf_is_a_parse_error_not_a_crash():
    links = ''.join(f'<link name="l{i}"/>' for i in range(2))
    deep = '<robot name="r">' + links + '<a>' * 5000 + '</a>' * 5000 + '</robot>'
    assert 'deeper' in refused(lambda: sources.from_model_text(deep), ResourceParseError)


def test_a_mesh_over_the_face_budget_is_refused_by_mjcf_before_mujoco_builds_it(tmp_path):
    binary_stl(tmp_path / 'big.stl', 300_000)  # 15 MB, under the byte budget
    model = tmp_path / 'm.xml'
    model.write_text('<mujoco><asset><mesh name="m" file="big.stl"/></asset><worldbody>'
                     '<body name="b"><freejoint/><geom type="mesh" mesh="m"/></body>'
                     '</worldbody></mujoco>')
    message = refused(lambda: sources.from_file(str(model), allowed_roots=[str(tmp_path)]),
                      UnsupportedAssetsError)
    # Our check's words, from the STL's header: MuJoCo never built it (its own refusal of a
    # binary STL over 200k faces says something else, after reading it all).
    assert message == assets.ERR_FACES.format(value='big.stl', n=300000,
                                              limit=WorldConfig().max_mesh_faces)


def test_resource_string_may_not_use_relative_paths_or_submodels(tmp_path):
    refused(lambda: sources.from_model_text(cube_texture(file='x.png'),
                                            allowed_roots=[str(tmp_path)]), MissingAssetsError)
    sub = (f'<mujoco><asset><model name="s" file="{tmp_path}/s.xml"/></asset>{BODY}'
           '</mujoco>')
    refused(lambda: sources.from_model_text(sub, allowed_roots=[str(tmp_path)]),
            UnsupportedFormatError)


def test_a_huge_entity_name_is_refused_with_a_short_message(world):
    message = refused(lambda: world.spawn('n' * 10_000_000, sources.primitive('box', [.05] * 3),
                                          position=[0, 1, 1]), NameInvalidError)
    assert len(message) < 500


def test_a_legit_model_with_its_own_folders_still_spawns_as_written(tmp_path, world):
    """The sandbox keeps MJCF's meaning: meshdir, texturedir, a cube texture, an include."""
    (tmp_path / 'meshes').mkdir()
    (tmp_path / 'textures').mkdir()
    import trimesh
    (tmp_path / 'meshes' / 'tri.stl').write_bytes(
        trimesh.creation.icosphere(subdivisions=1, radius=0.03).export(file_type='stl'))
    png(tmp_path / 'textures' / 'side.png')
    (tmp_path / 'materials.xml').write_text(
        '<mujoco><asset><texture name="t" type="cube" fileright="side.png" '
        'fileleft="side.png" fileup="side.png" filedown="side.png" filefront="side.png" '
        'fileback="side.png"/><material name="mat" texture="t"/></asset></mujoco>')
    model = tmp_path / 'robot.xml'
    model.write_text(
        '<mujoco><compiler meshdir="meshes" texturedir="textures"/>'
        '<include file="materials.xml"/><asset><mesh name="tri" file="tri.stl"/></asset>'
        '<worldbody><body name="base"><freejoint/><geom type="box" size=".05 .05 .05" '
        'material="mat"/><geom type="mesh" mesh="tri" mass=".1"/></body></worldbody>'
        '</mujoco>')
    src = sources.from_file(str(model), allowed_roots=[str(tmp_path)])
    world.spawn('robot2', src, position=[0, 1.5, 0.5])
    with world.locked() as (m, _):
        assert m.ntex >= 1 and m.nmesh >= 1
    world.spawn('robot3', sources.from_file(str(model), allowed_roots=[str(tmp_path)]),
                position=[0, -1.5, 0.5])  # twice: its assets do not collide
    world.delete('robot2')
    world.step(10)


def _rss_mib() -> float:
    for line in Path('/proc/self/status').read_text().splitlines():
        if line.startswith('VmRSS'):
            return int(line.split()[1]) / 1024
    raise RuntimeError('no VmRSS')


@pytest.mark.slow  # 25 s
def test_a_spawn_and_delete_storm_gives_its_memory_back(world):
    """Deleted entities leave nothing behind: not in the model, not in the process."""
    def storm(n: int) -> None:
        for i in range(n):
            world.spawn(f's{i}', sources.primitive('box', [0.05] * 3, mass=0.2),
                        position=[-3 + (i % 20) * 0.3, -3 + (i // 20) * 0.3, 1.0])
        for i in range(n):
            world.delete(f's{i}')

    def settled_rss() -> float:  # as the node's housekeeping leaves it, once a second
        gc.collect()
        release_free_memory()
        return _rss_mib()

    storm(200)  # warm-up: caches, the allocator's first growth
    before = settled_rss()
    for _ in range(2):
        storm(200)
    grown = settled_rss() - before
    # Issue 21's storm target. Each model kept alive would cost about 1 MiB, so 400 kept
    # models, or glibc keeping their freed heap (300 MiB measured), fail it; the RSS of an
    # idle process still moves by about 10 MiB either way (fragmentation), hence no tighter.
    assert grown < 50, f'RSS grew {grown:.0f} MiB over 400 spawns and deletes'
    assert [e.name for e in world.entities()] == ['robot', 'table', 'box_a', 'box_b']


def test_the_body_cap_refuses_a_spawn_past_it_and_says_which_limit():
    from sim_node.core.config import WorldConfig
    from sim_node.core.errors import CapacityError
    w = World.from_file(str(DEFAULT_SCENE), WorldConfig(max_bodies=12))
    names = [e.name for e in w.entities()]
    n0 = w.model_info.body_names.__len__()
    spawned = 0
    with pytest.raises(CapacityError, match='max_bodies'):
        for i in range(20):
            w.spawn(f'c{i}', sources.primitive('box', [0.05] * 3), position=[i * 0.3 - 2, 2, 1])
            spawned += 1
    assert n0 + spawned == 12  # filled exactly to the limit, then refused
    w.delete('c0')
    w.spawn('again', sources.primitive('box', [0.05] * 3), position=[0, -2, 1])  # room again
    assert [e.name for e in w.entities()][:len(names)] == names


def test_a_busy_trim_waits_until_enough_is_free_then_memory_goes_back():
    """The trim stalls allocations: a caller that asks for a lot free gets no trim short of it."""
    from sim_node.core.base.memory import free_heap_bytes
    if free_heap_bytes() is None:
        pytest.skip('not glibc 2.33 or later: no mallinfo2, every trim is made')
    blocks = [bytearray(4000) for _ in range(50_000)]  # 200 MB of heap blocks
    del blocks[:-1]  # freed, all but the last: the heap cannot shrink from its top
    held = _rss_mib()
    assert free_heap_bytes() >= 150 << 20
    assert not release_free_memory(at_least=1 << 40)
    assert _rss_mib() > held - 20  # kept
    assert release_free_memory(at_least=100 << 20)
    assert _rss_mib() < held - 150  # given back
