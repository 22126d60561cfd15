"""
The shape of the code, as a new maintainer meets it (issue 31).

No module reads a private name that another file defines (one class lives in one file; objects
talk through public methods), no module holds more than 400 lines of code (docstrings, comments
and blank lines not counted: sizes follow concepts, and prose is never cut to fit) and the node's
at most 250, and the README is a door of at most 200 lines whose map names exactly the package's
folders.
"""

import ast
import io
from pathlib import Path
import re
import tokenize

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ('sim_node', 'msg_adapters')
#: Private names of libraries that the project's classes use as their subclasses or callers:
#: (name, why).
LIBRARY_PRIVATES = {
    '_is_owned': "threading.RLock's: whether the calling thread holds it",
    '_exit': 'os._exit: leave at once when a callback still works at shutdown',
    '_add_info': "gymnasium.vector.VectorEnv's, for the vector env's infos",
    '_eval_dict': "xacro's table of $(eval) names, whose find() the isolated xacro replaces",
    '_get_sim': "mujoco.viewer.Handle's passive Simulate: its Run flag and a model reload (the "
                'only ways to a pause button and a new model without reopening the window)',
    '_address': "mujoco.MjModel's mjModel pointer: the one way to hand the model to MuJoCo's "
                'library through ctypes, which lets the GIL go while it makes a GL context',
}
#: Lines of code a module may hold (docstrings, comments and blank lines are not counted:
#: dm_control sizes modules by concept and keeps its prose; issue 51 replaced a 500-line cap
#: that was met by shortening docstrings).
MAX_CODE_LINES = 400
MAX_NODE_CODE_LINES = 250
MAX_README_LINES = 200


def modules() -> list:
    return sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob('*.py'))


def _defined_names(tree: ast.AST) -> set:
    """Every name a file defines: functions, classes, arguments, assigned names and attributes."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.arg):
            names.add(node.arg)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            names.add(node.attr)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        elif isinstance(node, ast.alias):
            names.add(node.asname or node.name.split('.')[-1])
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            names.add(node.value)  # __slots__ entries
    return names


def borrowed_privates(path: Path) -> list:
    """Return (line, name) of private names `path` reads that it does not define itself."""
    tree = ast.parse(path.read_text())
    own = _defined_names(tree)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            name = node.attr
            if (name.startswith('_') and not name.startswith('__') and name not in own
                    and name not in LIBRARY_PRIVATES):
                out.append((node.lineno, name))
        elif isinstance(node, ast.ImportFrom):
            out += [(node.lineno, a.name) for a in node.names
                    if a.name.startswith('_') and not a.name.startswith('__')]
    return out


def test_no_module_reads_a_private_name_another_file_defines():
    found = [f'{p.relative_to(ROOT)}:{line}: {name}' for p in modules()
             for line, name in borrowed_privates(p)]
    assert not found, '\n'.join(found)


def test_no_test_reads_a_private_name_of_the_package():
    """Tests use public APIs: ``world.stepping.live``, ``rig.contexts_made``, ``window.handle``."""
    tests = sorted((ROOT / 'test').rglob('*.py'))
    found = [f'{p.relative_to(ROOT)}:{line}: {name}' for p in tests
             for line, name in borrowed_privates(p)]
    assert not found, '\n'.join(found)


def test_the_check_sees_a_borrowed_private_name(tmp_path):
    """The checker itself: a mixin reading its host's private attribute is found."""
    mixin = tmp_path / 'mixin.py'
    mixin.write_text('class Mixin:\n    def f(self):\n        return self._model\n')
    host = tmp_path / 'host.py'
    host.write_text('class Host:\n    def __init__(self):\n        self._model = 1\n')
    assert borrowed_privates(mixin) == [(3, '_model')]
    assert borrowed_privates(host) == []


def code_lines(text: str) -> int:
    """Return how many lines of `text` hold code: not docstrings, comments or blank lines."""
    prose = set()
    for node in ast.walk(ast.parse(text)):
        # Docstrings of modules, classes and functions, and strings standing as statements
        # (attribute docstrings).
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) \
                and isinstance(node.value.value, str):
            prose.update(range(node.lineno, node.end_lineno + 1))
    code = set()
    skip = (tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
            tokenize.ENDMARKER)
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type not in skip:
            code.update(range(tok.start[0], tok.end[0] + 1))
    return len(code - prose)


def test_no_module_holds_over_400_lines_of_code_and_the_node_at_most_250():
    sizes = {p.relative_to(ROOT).as_posix(): code_lines(p.read_text()) for p in modules()}
    assert {p: n for p, n in sizes.items() if n > MAX_CODE_LINES} == {}
    assert sizes['sim_node/ros/node/node.py'] <= MAX_NODE_CODE_LINES


def test_the_size_count_leaves_prose_out():
    """The counter itself: a docstring, comments and blank lines add nothing; code does."""
    text = ('"""A module.\n\nIts long story.\n"""\n\n# why\n\ndef f(x):\n'
            '    """Say what f does."""\n    #: a note\n    return (x +\n            1)\n')
    assert code_lines(text) == 3  # def, and the two lines of the return


def test_only_the_ros_folder_and_the_adapters_import_rclpy():
    """The core, the session, the Gym envs, the viewer and the recorder run without ROS."""
    ros_free = [p for p in modules() if p.parts[len(ROOT.parts)] == 'sim_node'
                and p.parts[len(ROOT.parts) + 1] != 'ros']
    bad = [str(p.relative_to(ROOT)) for p in ros_free
           if re.search(r'^\s*(from|import) (rclpy|rosgraph_msgs|std_msgs|sensor_msgs|'
                        r'geometry_msgs|simulation_interfaces|tf2_msgs)\b', p.read_text(),
                        re.M)]
    assert not bad


def _readme_map() -> set:
    """Return the folders the README's map names (lines of its map block: `path/`)."""
    text = (ROOT / 'README.md').read_text()
    block = re.search(r'<!-- map -->\n```text\n(.*?)```', text, re.S)
    assert block, 'the README has no map block (<!-- map --> then a ```text block)'
    return {m.group(1).rstrip('/') for m in re.finditer(r'^\s*([\w./-]+/)\s', block.group(1),
                                                        re.M)}


def test_the_readme_is_a_door_and_its_map_matches_the_folders():
    text = (ROOT / 'README.md').read_text()
    assert len(text.splitlines()) <= MAX_README_LINES
    folders = {p.relative_to(ROOT).as_posix() for pkg in PACKAGES
               for p in [ROOT / pkg, *(ROOT / pkg).rglob('*')]
               if p.is_dir() and (p / '__init__.py').is_file()}
    named = _readme_map()
    assert folders <= named, f'folders the map leaves out: {sorted(folders - named)}'
    missing = sorted(n for n in named if not (ROOT / n).is_dir())
    assert not missing, f'the map names folders that do not exist: {missing}'


@pytest.mark.parametrize('doc', sorted(p.name for p in (ROOT / 'docs').glob('*.md')))
def test_every_link_of_the_readme_and_docs_leads_somewhere(doc):
    for source in (ROOT / 'README.md', ROOT / 'docs' / doc):
        for target in re.findall(r'\]\(([^)#:]+)(?:#[^)]*)?\)', source.read_text()):
            assert (source.parent / target).exists(), f'{source.name} links to {target}'


@pytest.mark.parametrize('old, new, name', [
    ('sim_node.core.sources', 'sim_node.core.models.sources', 'primitive'),
    ('sim_node.core.bases', 'sim_node.core.control.bases', 'Odometry'),
    ('sim_node.core.config', 'sim_node.core.base.config', 'WorldConfig'),
    ('sim_node.core.errors', 'sim_node.core.base.errors', 'SimError'),
    ('sim_node.core.records', 'sim_node.core.base.records', 'Snapshot'),
    ('sim_node.gym_env', 'sim_node.gym.env', 'Task'),
    ('sim_node.client', 'sim_node.ros.client', 'SimClient'),
    ('sim_node.qos', 'sim_node.ros.settings.qos', 'SERVICE_QOS'),
])
def test_the_import_paths_older_code_uses_still_work(old, new, name):
    import importlib
    assert getattr(importlib.import_module(old), name) is \
        getattr(importlib.import_module(new), name)


# ------------------------------------------------------------------ dependencies point up (B7)

#: What the core may import of the package: only itself. Never a front-end (view, record), the
#: ROS skin, the Gym envs, the Session or the Simulation, not even inside a function.
CORE = 'sim_node.core'


def module_name(path: Path, root: Path = ROOT) -> str:
    parts = list(path.relative_to(root).with_suffix('').parts)
    return '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)


def package_imports(paths: list, root: Path = ROOT) -> dict:
    """
    Return {module: {(line, imported module)}} for every import of the package's own modules.

    Every import statement counts, at module level or inside a function or a branch; ``from
    a import b`` names ``a.b`` when that is a module, else ``a``.
    """
    names = {module_name(p, root): p for p in paths}

    def own(name: str):
        while name and name not in names:
            name = name.rpartition('.')[0]
        return name or None

    found = {}
    for mod, path in names.items():
        package = mod if path.name == '__init__.py' else mod.rpartition('.')[0]
        deps = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split('.')[:len(package.split('.')) - node.level + 1]
                    base_name = '.'.join(base + ([node.module] if node.module else []))
                else:
                    base_name = node.module
                targets = [f'{base_name}.{a.name}' if f'{base_name}.{a.name}' in names
                           else base_name for a in node.names]
            else:
                continue
            deps |= {(node.lineno, t) for t in map(own, targets) if t and t != mod}
        found[mod] = deps
    return found


def import_cycles(graph: dict) -> list:
    """Return the import cycles of `graph` ({module: {(line, module)}}): sorted module lists."""
    edges = {m: sorted({d for _, d in deps}) for m, deps in graph.items()}
    order, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(v):  # Tarjan's strongly connected components
        order[v] = low[v] = len(order)
        stack.append(v)
        on_stack.add(v)
        for w in edges.get(v, ()):
            if w not in order:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], order[w])
        if low[v] == order[v]:
            part = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                part.append(w)
                if w == v:
                    break
            if len(part) > 1:
                cycles.append(sorted(part))
    for v in sorted(edges):
        if v not in order:
            visit(v)
    return cycles


def core_upward_imports(graph: dict) -> list:
    """Return 'module:line imports name' for every import from the core to outside it."""
    return [f'{m}:{line} imports {d}' for m, deps in sorted(graph.items())
            if m == CORE or m.startswith(CORE + '.')
            for line, d in sorted(deps) if not (d == CORE or d.startswith(CORE + '.'))]


def test_the_core_imports_nothing_above_it_and_no_module_is_in_an_import_cycle():
    graph = package_imports(modules())
    assert len(graph) > 90 and any(m.startswith(CORE + '.') for m in graph)
    assert core_upward_imports(graph) == []
    assert import_cycles(graph) == []


def folder_of(module: str, root: Path = ROOT) -> str:
    """Return the package (folder) a module lives in; a package is its own folder."""
    path = root / module.replace('.', '/')
    return module if (path / '__init__.py').is_file() else module.rpartition('.')[0]


def folder_imports(graph: dict, root: Path = ROOT) -> dict:
    """Return the import graph between folders: {folder: {(line, folder)}} of `graph`'s."""
    out: dict = {}
    for mod, deps in graph.items():
        here = folder_of(mod, root)
        out.setdefault(here, set())
        out[here] |= {(line, folder_of(d, root)) for line, d in deps
                      if folder_of(d, root) != here}
    return out


def test_folders_are_layers_no_import_between_folders_runs_back_up():
    """
    Tarjan over folders as well as modules (issue 51).

    At d48b79a, core's root, stepping/, editing/, control/, models/ and devices/ formed one
    cycle (the loop and the cameras read the World facade above them; the index read devices),
    and the ROS layer's files sat in one folder.
    """
    graph = folder_imports(package_imports(modules()))
    assert 'sim_node.core.stepping' in graph and 'sim_node.ros.control' in graph
    assert import_cycles(graph) == []


def test_the_import_check_sees_a_function_level_import_and_a_cycle(tmp_path):
    """The checker itself, on a package shaped like the one before issue 41."""
    core = tmp_path / 'sim_node' / 'core'
    core.mkdir(parents=True)
    (tmp_path / 'sim_node' / '__init__.py').write_text('')
    (core / '__init__.py').write_text('')
    (core / 'loop.py').write_text('from .world import World\n\n\ndef start():\n'
                                  '    from ..view.window import Window\n')
    (core / 'world.py').write_text('import numpy\n')
    view = tmp_path / 'sim_node' / 'view'
    view.mkdir()
    (view / '__init__.py').write_text('')
    (view / 'window.py').write_text('from ..core import loop\n')
    graph = package_imports(sorted(tmp_path.rglob('*.py')), tmp_path)
    assert core_upward_imports(graph) == ['sim_node.core.loop:5 imports sim_node.view.window']
    assert import_cycles(graph) == [['sim_node.core.loop', 'sim_node.view.window']]
    # Between folders: core -> view -> core.
    assert import_cycles(folder_imports(graph, tmp_path)) == [['sim_node.core',
                                                               'sim_node.view']]


# ------------------------------------------------------------------ core/ by job, with maps

def docstring_map(package: Path) -> set:
    """Return the children a package's docstring names as ``:mod:`.name``` (first part)."""
    doc = ast.get_docstring(ast.parse((package / '__init__.py').read_text())) or ''
    return {m.split('.')[0] for m in re.findall(r':mod:`\.([\w.]+)`', doc)}


def children(package: Path) -> set:
    """Return the modules and subpackages a package holds (not its ``__init__``)."""
    return {p.stem for p in package.glob('*.py') if p.name != '__init__.py'} | \
        {p.name for p in package.iterdir() if (p / '__init__.py').is_file()}


#: Every package of the project: the core's folders, the ROS rooms, the front-ends (issue 51:
#: at d48b79a only the core's maps were checked, and ros/ was 28 flat files).
PACKAGES_WITH_MAPS = sorted(p.parent.relative_to(ROOT).as_posix() for pkg in PACKAGES
                            for p in (ROOT / pkg).rglob('__init__.py'))


@pytest.mark.parametrize('package', PACKAGES_WITH_MAPS)
def test_each_package_s_docstring_maps_exactly_the_modules_it_holds(package):
    folder = ROOT / package
    named, held = docstring_map(folder), children(folder)
    assert not held - named, f'{package} holds modules its map leaves out: {sorted(held - named)}'
    assert not named - held, f'{package} maps modules it does not hold: {sorted(named - held)}'


def test_the_core_is_folders_by_job():
    """The jobs of the core have folders of their own, not files side by side."""
    core = ROOT / 'sim_node' / 'core'
    assert {'stepping', 'editing', 'control', 'models', 'devices'} <= children(core)
    flat = {p.stem for p in core.glob('*.py') if p.name != '__init__.py'}
    assert len(flat) <= 16, sorted(flat)


#: What writes a rotation: MuJoCo's quaternion routines and half-angle quaternion formulas.
ROTATION_CODE = re.compile(r'mju_(axisAngle2Quat|mulQuat|quat2Mat|mat2Quat|rotVecQuat|negQuat|'
                           r'euler2Quat)|(cos|sin)\(\w+(\.\w+)? / 2\)|atan2\(2 \*')


def test_rotations_are_written_only_in_quat():
    """
    Rotations in one place (issue 51): at d48b79a they were written in six files besides it.

    Every other module calls :mod:`sim_node.core.base.quat` (from_rpy, to_rpy, from_yaw,
    yaw_of, from_axis_angle, from_matrix, ...).
    """
    quat = ROOT / 'sim_node' / 'core' / 'base' / 'quat.py'
    found = [f'{p.relative_to(ROOT)}:{n}' for p in modules() if p != quat
             for n, line in enumerate(p.read_text().splitlines(), 1)
             if ROTATION_CODE.search(line)]
    assert found == [], found
    assert ROTATION_CODE.search('mujoco.mju_mulQuat(out, a, b)')  # the check itself
    assert ROTATION_CODE.search('np.array([math.cos(yaw / 2), 0, 0, math.sin(yaw / 2)])')


#: Planar odometry integrated (a heading advanced by a turn, a position by the mean heading or
#: an arc), or an Odometry message built field by field.
ODOMETRY_CODE = re.compile(r'\byaw\s*\+\s*d(yaw|th)\b|\bOdometry\(\)')


def test_odometry_is_integrated_and_built_in_one_place_each():
    """
    One planar odometry (core/control/odometry.py) and one Odometry builder (issue 51).

    At d48b79a three integrators (the node's bases, diff_drive_controller's, the steering
    controllers') and two message builders (msg_adapters/odometry.py, ros/control) did it.
    """
    one = {ROOT / 'sim_node' / 'core' / 'control' / 'odometry.py',
           ROOT / 'msg_adapters' / 'odometry.py'}
    found = [f'{p.relative_to(ROOT)}:{n}' for p in modules() if p not in one
             for n, line in enumerate(p.read_text().splitlines(), 1)
             if ODOMETRY_CODE.search(line)]
    assert found == [], found
    assert ODOMETRY_CODE.search('mid = self.yaw + dyaw / 2.0')  # the check itself
    assert ODOMETRY_CODE.search('    msg = Odometry()')


def code_md_modules(text: str) -> set:
    """
    Return each module docs/code.md names, as a path from the root, with the folder it says.

    A section ``## `sim_node/x/`...`` sets the folder; a table's header ``| `sub/` |`` or a
    row's first cell ``| `room/` |`` (the ROS layer's rooms), or a paragraph opening with the
    folder in backquotes and a colon, a sub-folder of it (a folder from the root where one is
    there, as ``msg_adapters``); every backquoted ``name.py`` after is a module there, until
    the table or the paragraph ends.
    """
    named, section, folder = set(), None, None
    for line in text.splitlines():
        heading = re.match(r'## `(sim_node/[\w/]*?)/?`', line)
        if line.startswith('## '):
            section = folder = heading.group(1) if heading else None
            continue
        if section is None:
            continue
        if not line.strip():
            folder = section  # a table or a paragraph ended
            continue
        cells = [c.strip() for c in line.strip().strip('|').split('|')] if '|' in line else []
        if cells and cells[0].startswith('---'):
            continue
        sub = re.fullmatch(r'`([\w/]+?)/`', cells[0]) if cells \
            else re.match(r'`([\w/]+?)/`:', line)
        where = folder
        if sub:
            where = sub.group(1) if (ROOT / sub.group(1)).is_dir() \
                else f'{section}/{sub.group(1)}'
            if not cells or (len(cells) == 2 and '.py' not in cells[1]):
                folder = where  # a table's header or a paragraph's opening: until it ends
        for name in re.findall(r'`(\w+\.py)`', line):
            if not (ROOT / 'test' / name).is_file():  # a test named in passing
                named.add(f'{where}/{name}')
    return named


def test_docs_code_md_names_every_module_where_it_is():
    """
    docs/code.md's map, claim by claim: each module it names is where it says (issue 51).

    And each module of the folders it maps is named; its size rule is the one tested here.
    """
    text = (ROOT / 'docs' / 'code.md').read_text()
    named = code_md_modules(text)
    missing = sorted(p for p in named if not (ROOT / p).is_file())
    assert missing == [], missing
    folders = {p.rsplit('/', 1)[0] for p in named}
    unnamed = sorted(p.relative_to(ROOT).as_posix() for f in folders
                     for p in (ROOT / f).glob('*.py')
                     if p.name != '__init__.py' and p.relative_to(ROOT).as_posix() not in named)
    assert unnamed == [], unnamed
    assert f'{MAX_CODE_LINES} lines of code' in text and f'at most {MAX_NODE_CODE_LINES}' in text
    assert 'sim_node/core/control/laws.py' in named and 'sim_node/ros/node/status.py' in named


def test_docs_threading_md_lists_every_thread_and_every_lock():
    """
    Every thread the package names and every lock it keeps is in docs/threading.md (issue 51).

    At fdc47ee the mesh converters', xacro's and the vector env's threads were missing.
    """
    text = (ROOT / 'docs' / 'threading.md').read_text()
    threads, locks = set(), set()
    for path in modules():
        source = path.read_text()
        threads.update(re.findall(r"name=f?'(sim-[a-z-]+)", source))
        locks.update(re.findall(r'(?:self\.)?(\w+) = threading\.(?:R?Lock|Condition)\(',
                                source))
    assert {'sim-loop', 'sim-meshes', '_stage_lock', 'requests_lock'} <= threads | locks
    assert sorted(t for t in threads if f'`{t}' not in text) == []
    assert sorted(n for n in locks if n not in text) == []


def test_the_controllers_laws_are_in_the_core_and_their_ros_side_is_topics():
    """
    The ROS side of the controllers imports none of the law's parts (issue 51, item 2).

    At fdc47ee the bases' timeouts, limiters, kinematics and odometry ran in ros/control, on
    the joint_states publisher's thread; now :mod:`sim_node.core.control.laws` runs them on
    the stepping side and ros/control keeps the topics, services and actions.
    """
    law_parts = {'limits', 'diff_drive', 'steering', 'odometry', 'wheels', 'drives'}
    found = []
    for path in sorted((ROOT / 'sim_node' / 'ros' / 'control').glob('*.py')):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or '').startswith('core.control'):
                tail = node.module.split('.')[2:3]
                names = set(tail) if tail else {a.name for a in node.names}
                found += [f'{path.name}:{node.lineno} {n}' for n in names & law_parts]
    assert found == [], found


def test_the_ros_layer_is_rooms_by_job():
    """A new engineer finds where a controller ticks: ros/ holds rooms, not flat files."""
    ros = ROOT / 'sim_node' / 'ros'
    assert {'node', 'services', 'topics', 'commands', 'control', 'client'} <= children(ros)
    flat = {p.stem for p in ros.glob('*.py') if p.name != '__init__.py'}
    assert flat == set(), sorted(flat)


def test_the_map_check_sees_a_module_left_out_and_one_that_is_gone(tmp_path):
    (tmp_path / '__init__.py').write_text('"""Jobs: :mod:`.loop` (steps), :mod:`.gone`."""\n')
    (tmp_path / 'loop.py').write_text('')
    (tmp_path / 'new.py').write_text('')
    assert docstring_map(tmp_path) == {'loop', 'gone'}
    assert children(tmp_path) == {'loop', 'new'}


def test_each_controller_type_is_one_class_in_one_registry_with_its_schema_in_the_docs():
    """
    A controller type is written once (issue 51): its class, schema and checks in the core.

    At d48b79a each type was written in three places (TYPES, an if-chain in configure, an
    if-chain in the ROS layer's runtime_for) and its parameters were read twice with separate
    defaults. Now the registry names every type, the ROS layer maps each class to a runtime,
    and docs/controllers.md holds the tables the schemas print.
    """
    from sim_node.core.control import controller_types as types
    from sim_node.ros.control.controller_manager import RUNTIMES
    assert set(RUNTIMES) == set(types.REGISTRY.values())
    assert types.TYPES == {name: cls.base for name, cls in types.REGISTRY.items()}
    text = (ROOT / 'docs' / 'controllers.md').read_text()
    block = re.search(r'<!-- controller parameters:[^\n]*-->\n(.*?)'
                      r'<!-- /controller parameters -->', text, re.S)
    assert block and block.group(1) == types.markdown(), \
        'docs/controllers.md is out of date: python -m sim_node.core.control.controller_types'
    for cls in types.REGISTRY.values():
        assert cls.summary and all(p.description for p in cls.parameters), cls
    # No type name is written as a value (compared, a key) outside the registry's module.
    found = [f'{p.relative_to(ROOT)}:{node.lineno}' for p in modules()
             if p.name != 'controller_types.py'
             for node in ast.walk(ast.parse(p.read_text()))
             if isinstance(node, ast.Constant) and node.value in types.REGISTRY]
    assert found == [], found


def test_the_parameter_reference_is_the_table_the_node_declares_from():
    """docs/parameters.md holds what ``python -m sim_node.ros.settings.parameter_table`` prints."""
    from sim_node.ros.settings.parameter_table import markdown, PARAMETERS
    text = (ROOT / 'docs' / 'parameters.md').read_text()
    block = re.search(r'<!-- parameters:[^\n]*-->\n(.*?)<!-- /parameters -->', text, re.S)
    assert block, 'docs/parameters.md has no generated block'
    assert block.group(1) == markdown(), \
        'docs/parameters.md is out of date: python -m sim_node.ros.settings.parameter_table'
    names = [p.name for p in PARAMETERS]
    assert len(names) == len(set(names)) > 50
    params = (ROOT / 'sim_node' / 'ros' / 'settings' / 'params.py').read_text()
    assert 'declare_parameter(spec.name' in params and params.count('declare_parameter(') == 1


def test_what_comes_and_goes_with_models_is_made_without_qos_event_handlers():
    """
    A publisher or subscription made after the node's start is made without QoS event handlers.

    rclpy puts a destroyed one's handlers into the executor's next wait set anyway, and
    ``spin()`` then raises InvalidHandle, ending the node: a gz-sim system's subscription,
    destroyed as a world was loaded again, did (issue 54). Made in a constructor, it lives as
    long as the node; the client tools (``ros/client``) and the start (``ros/node``) run once.
    """
    found = []
    for p in sorted((ROOT / 'sim_node' / 'ros').rglob('*.py')):
        if p.parent.name in ('client', 'node'):
            continue
        for fn in ast.walk(ast.parse(p.read_text())):
            if not isinstance(fn, ast.FunctionDef) or fn.name == '__init__':
                continue
            found += [f'{p.relative_to(ROOT)}:{n.lineno}' for n in ast.walk(fn)
                      if isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute)
                      and n.func.attr in ('create_subscription', 'create_publisher')
                      and not any(k.arg in ('event_callbacks', None) for k in n.keywords)]
    assert found == [], found
