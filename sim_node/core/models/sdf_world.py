"""
An SDF world made one MJCF world, and an SDF model made one spawnable spec.

A world (:func:`world`): its ``<physics>`` (``max_step_size`` the timestep, ODE's or Bullet's
solver ``<iters>`` MuJoCo's most iterations, ``real_time_factor`` kept for the loop),
``<gravity>`` and ``<magnetic_field>`` (in ``<physics>`` before SDF 1.6), ``<scene>`` (its
ambient light as the headlight's, its background as the sky), its lights, its
``<spherical_coordinates>`` (kept) and each top-level model an entity named by it. A model
that is only bodies (no sensor, plugin or ``ros2_control``; one tree) is written into the
world itself, named as a spawn would name it, so that a world of 3,000 shapes is one document
MuJoCo reads and compiles once; any other is made on its own (:func:`model`) and attached as
a spawn is (:attr:`WorldPlan.entities`), keeping its records (sensors, drive, controllers)
like a spawned robot's. A model included from a URDF file is attached from it.

The plan names what it did not read (:mod:`.sdf_elements`) and the systems it does not run
(:mod:`.sdf_systems`); nothing here touches a live world.
"""

from dataclasses import dataclass, field, replace
import re
from typing import Optional
import xml.etree.ElementTree as ET

import mujoco

from . import decompose, ros2_control, sdf_elements, sdf_model, sdf_systems, urdf_declared
from .prepare import compile_error
from .sdf_frames import parse_pose, Pose, pose_attr, Scope, version_of
from .sdf_parts import light
from .sdf_read import Expanded, URDF_FILE
from .sdf_shapes import Assets, numbers
from .urdf import Prepared
from ..base import checks
from ..base.errors import ResourceParseError
from ..base.records import (DeclaredCamera, DeclaredGeo, DeclaredImu, DeclaredLaser, NO_TOPIC,
                            ORIGIN_NUMERIC)

#: The solver iterations MuJoCo keeps at least (Newton converges in a few; SDF's ODE counts
#: its own, cheaper ones).
MIN_ITERATIONS = 10
#: Colour of the sky when a world's scene names none (Gazebo's grey).
DEFAULT_BACKGROUND = (0.7, 0.7, 0.7)

ERR_NO_WORLD = ('the SDF file holds no <world> (it holds {what}): load a world file, or spawn '
                'a model file with spawn_entity')
ERR_NO_MODEL = ('the SDF holds no <model> to spawn{what}: a world file is loaded with '
                'load_world')
ERR_TWICE = 'the world has two models named {name!r}: SDF names models once per world'


@dataclass
class Entity:
    """
    A model of a world made on its own and attached as a spawn is.

    :param spec: its spec in its own names (None for a URDF: :attr:`urdf` names the file).
    :param notes: what it declares, as a URDF's :class:`.urdf.Prepared`.
    """

    name: str
    pose: Pose
    spec: Optional[mujoco.MjSpec] = None
    notes: Optional[Prepared] = None
    urdf: str = ''
    static: bool = False
    description: str = ''


#: SDF's default ``<magnetic_field>`` (tesla), which a world that names none has.
SDF_MAGNETIC_FIELD = '5.5645e-06 2.28758e-05 -4.23884e-05'


@dataclass
class WorldPlan:
    """An SDF world made MJCF: the world's spec, the entities to attach, what it said."""

    spec: mujoco.MjSpec
    name: str
    entities: list = field(default_factory=list)
    real_time_factor: Optional[float] = None
    spherical_coordinates: Optional[dict] = None
    not_read: list = field(default_factory=list)
    systems: list = field(default_factory=list)
    notes: list = field(default_factory=list)


def world(expanded: Expanded, reader, places) -> WorldPlan:
    """Make the MJCF world of an expanded SDF document (see the module docstring)."""
    w = expanded.world
    if w is None:
        kinds = sorted({e.tag for e in expanded.root}) or ['nothing']
        raise ResourceParseError(ERR_NO_WORLD.format(what=', '.join(f'<{k}>' for k in kinds)))
    name = w.get('name') or 'world'
    scope = Scope(w, expanded.version)
    out = Assets(reader, places, skipped=expanded.skipped)
    doc = ET.Element('mujoco', model=name)
    ET.SubElement(doc, 'compiler', angle='radian', autolimits='true')
    plan = WorldPlan(spec=None, name=name)
    _physics(w, expanded.version, doc, plan)
    body = ET.SubElement(doc, 'worldbody')
    contact, equality = ET.Element('contact'), ET.Element('equality')
    colour_geoms = []
    seen = set()
    for elem in w:
        if elem.tag == 'light':
            where = f'light {elem.get("name")!r}'
            pose = scope.place(parse_pose(elem.find('pose'), where),
                               pose_attr(elem.find('pose'), scope.version), where)
            body.append(light(elem, pose, elem.get('name') or f'light_{len(body)}', where))
            continue
        if elem.tag != 'model':
            continue
        given = elem.get('name', '')
        if given in seen:
            raise ResourceParseError(ERR_TWICE.format(name=given))
        seen.add(given)
        pose = scope.pose(given)
        mname = entity_name(given, seen)
        if mname != given:
            plan.notes.append(f'the model {given!r} is the entity {mname!r} (names here are '
                              "letters, digits, '_' and '-')")
        static = (elem.findtext('static') or '').strip().lower() in ('true', '1')
        if elem.get(URDF_FILE):
            plan.entities.append(Entity(mname, pose, urdf=elem.get(URDF_FILE), static=static,
                                        description=f'URDF model {mname}'))
            continue
        topics = gz_topics(name, mname)
        version = version_of(elem, expanded.version)
        if not _declares(elem):
            built = sdf_model.build(elem, version, out, entity=mname, at=pose, topics=topics)
            if len(built.bodies) == 1:
                body.extend(built.bodies)
                contact.extend(built.excludes)
                equality.extend(built.equalities)
                colour_geoms += built.mesh_colour
                plan.notes += built.notes
                if built.decompose or (built.moving_joints == 0 and decompose.mode() != 'none'):
                    _mark(built, doc)
                continue
        spec, notes = model(elem, version, reader, places, static, topics, name,
                            skipped=expanded.skipped)
        plan.entities.append(Entity(mname, pose, spec, notes, static=static,
                                    description=f'SDF model {mname}'))
    _finish_assets(doc, out, colour_geoms)
    step = float(doc.find('option').get('timestep', '0.002'))
    for eq in equality.iter('joint'):  # mimics and screws without give, as Gazebo's
        eq.set('solref', f'{2 * step:.6g} 1')
    for joint in body.iter('joint'):  # joint stops as hard as a step allows, as Gazebo's
        if joint.get('limited') == 'true':
            joint.set('solreflimit', f'{2 * step:.6g} 1')
    for i, eq in enumerate(equality):  # named, as every element with state (World: named)
        eq.set('name', eq.get('name') or f'equality_{i}')
    for extra in (contact, equality):
        if len(extra):
            doc.append(extra)
    plan.not_read = sdf_elements.not_read(expanded.root)
    plan.systems = sdf_systems.world_systems(w)
    plan.notes += out.notes
    marked = {m.get('mesh') for m in doc.iter('sim-decompose')}
    most = {}
    for m in doc.iter('sim-decompose'):
        if m.get('most'):
            most[m.get('mesh')] = min(most.get(m.get('mesh'), decompose.MAX_PARTS),
                                      int(m.get('most')))
    plan.spec = _spec(doc)
    if marked:
        decompose.split_geoms(plan.spec, {}, only=marked, max_parts=most)
    decompose.bound_hulls(plan.spec)
    return plan


def entity_name(name: str, taken=()) -> str:
    """
    Return the entity name of a model's name: itself where the world takes it, else made so.

    Gazebo takes any name (``Amazon Pod``, ``roboschool/stadium/part0.obj``); an entity's is
    letters, digits, ``_`` and ``-`` (it names TF frames and ROS topics): the rest become
    ``_``, a leading digit gets one before it, and a name taken gets ``_<n>``.
    """
    if checks.NAME_RE.match(name or ''):
        return name
    safe = re.sub(r'[^A-Za-z0-9_-]', '_', name or 'model')[:120] or 'model'
    if not re.match(r'[A-Za-z_]', safe):
        safe = f'_{safe}'[:120]
    out, i = safe, 0
    while out in taken:
        i += 1
        out = f'{safe}_{i}'
    return out


def _declares(model: ET.Element) -> bool:
    """Whether a model declares what a record keeps: sensors, plugins, ros2_control."""
    return any(e.tag in ('sensor', 'plugin', 'ros2_control') for e in model.iter())


def _mark(built, doc: ET.Element) -> None:
    """Mark a world model's mesh collisions to be split into convex parts (its rules)."""
    for geom in (g for b in built.bodies for g in b.iter('geom')):
        name = geom.get('name', '')
        how, most = built.decompose.get(name, ('', ''))
        if geom.get('type') == 'mesh' and geom.get('contype') != '0' and \
                how != 'convex_hull' and (how == 'convex_decomposition'
                                          or built.moving_joints == 0):
            ET.SubElement(doc, 'sim-decompose', mesh=geom.get('mesh'),
                          most=most if how == 'convex_decomposition' else '')


def _physics(w: ET.Element, version: tuple, doc: ET.Element, plan: WorldPlan) -> None:
    """Write a world's physics, gravity, field, scene and sky; keep its pace and place."""
    physics = w.find('physics')
    option = ET.SubElement(doc, 'option', integrator='implicitfast')
    if physics is not None:
        step = physics.findtext('max_step_size')
        if step is not None and step.strip():
            (dt,) = numbers(step, (0.001,), 'the world', '<max_step_size>')
            if not 0 < dt <= 0.1:
                raise ResourceParseError(f"the world's <max_step_size> {dt:g} is not in "
                                         '(0, 0.1] s')
            option.set('timestep', f'{dt:.12g}')
        rtf = physics.findtext('real_time_factor')
        if rtf is not None and rtf.strip():
            (factor,) = numbers(rtf, (1.0,), 'the world', '<real_time_factor>')
            if factor < 0:
                raise ResourceParseError("the world's <real_time_factor> is below zero")
            plan.real_time_factor = factor
        iters = physics.findtext('ode/solver/iters') or physics.findtext('bullet/solver/iters')
        if iters is not None and iters.strip().isdigit():
            option.set('iterations', str(max(MIN_ITERATIONS, min(int(iters), 1000))))
    for tag in ('gravity', 'magnetic_field'):
        text = w.findtext(tag) if w.find(tag) is not None else (
            physics.findtext(tag) if physics is not None else None)
        if text is not None and text.strip():
            values = numbers(text, (0, 0, -9.8), 'the world', f'<{tag}>')
            option.set('gravity' if tag == 'gravity' else 'magnetic',
                       ' '.join(f'{v:.12g}' for v in values))
    scene = w.find('scene')
    visual = ET.SubElement(doc, 'visual')
    ET.SubElement(visual, 'global', offwidth='640', offheight='480')
    sky = DEFAULT_BACKGROUND
    if scene is not None:
        ambient = scene.findtext('ambient')
        if ambient is not None and ambient.strip():
            a = numbers(ambient, (0.4, 0.4, 0.4, 1) if len(ambient.split()) == 4
                        else (0.4, 0.4, 0.4), 'the scene', '<ambient>')
            ET.SubElement(visual, 'headlight', ambient=' '.join(f'{min(v, 1):.4g}'
                                                                for v in a[:3]))
        bg = scene.findtext('background')
        if bg is not None and bg.strip():
            sky = numbers(bg, (0.7, 0.7, 0.7, 1) if len(bg.split()) == 4 else (0.7, 0.7, 0.7),
                          'the scene', '<background>')[:3]
    asset = ET.SubElement(doc, 'asset')
    ET.SubElement(asset, 'texture', name='sky', type='skybox', builtin='gradient',
                  rgb1=' '.join(f'{min(c, 1):.4g}' for c in sky),
                  rgb2=' '.join(f'{min(c, 1) * 0.6:.4g}' for c in sky), width='64',
                  height='64')
    if w.find('magnetic_field') is None and (physics is None or
                                             physics.find('magnetic_field') is None):
        option.set('magnetic', SDF_MAGNETIC_FIELD)  # SDF's default, not MuJoCo's
    coords = w.find('spherical_coordinates')
    if coords is not None:
        plan.spherical_coordinates = {e.tag: (e.text or '').strip() for e in coords}
        origin = [numbers(coords.findtext(tag) or '0', (0.0,), 'the world',
                          f'<spherical_coordinates><{tag}>')[0]
                  for tag in ('latitude_deg', 'longitude_deg', 'elevation', 'heading_deg')]
        if not (-90 <= origin[0] <= 90 and -180 <= origin[1] <= 360):
            raise ResourceParseError(
                f"the world's <spherical_coordinates> latitude {origin[0]:g} and longitude "
                f'{origin[1]:g} are not a place on the Earth (degrees)')
        custom = ET.SubElement(doc, 'custom')
        ET.SubElement(custom, 'numeric', name=ORIGIN_NUMERIC,
                      data=' '.join(f'{v:.12g}' for v in origin))


def _finish_assets(doc: ET.Element, out: Assets, colour_geoms: list) -> None:
    """Convert the document's meshes, colour mesh visuals from their files, add the assets."""
    colours = out.finish()
    for geom in colour_geoms:
        rgba = colours.get(geom.get('mesh', ''))
        if rgba is not None:
            geom.set('rgba', ' '.join(f'{c:.4g}' for c in rgba))
    asset = doc.find('asset')
    if asset is None:
        asset = ET.SubElement(doc, 'asset')
    asset.extend(out.elements)


def _spec(doc: ET.Element) -> mujoco.MjSpec:
    for m in list(doc.iter('sim-decompose')):
        doc.remove(m)
    try:
        return mujoco.MjSpec.from_string(ET.tostring(doc, encoding='unicode'))
    except ValueError as exc:
        raise compile_error(exc) from None


def model(elem: ET.Element, version: tuple, reader, places, static: bool = False,
          topics=None, world: str = 'default', skipped: Optional[list] = None) -> tuple:
    """
    Return (spec in the model's own names, its :class:`.urdf.Prepared` notes) of a model.

    :param static: the spawn (or an include) makes it static whatever its file says.
    :param world: the name of the world it goes into (gz-sim's default topics hold it).
    """
    if static:
        for old in elem.findall('static'):
            elem.remove(old)
        ET.SubElement(elem, 'static').text = 'true'
    out = Assets(reader, places, skipped=skipped)
    built = sdf_model.build(elem, version, out, topics=topics or gz_topics(
        world, entity_name(elem.get('name', ''))))
    doc = ET.Element('mujoco', model=built.name)
    ET.SubElement(doc, 'compiler', angle='radian', autolimits='true')
    ET.SubElement(doc, 'worldbody').extend(built.bodies)
    _finish_assets(doc, out, built.mesh_colour)
    for tag, items in (('contact', built.excludes), ('equality', built.equalities)):
        if items:
            ET.SubElement(doc, tag).extend(items)
    spec = _spec(doc)
    extensions = built.extensions + [ET.Element('gazebo')]
    extensions[-1].extend(p for p in elem.iter('plugin') if _model_plugin(elem, p))
    extensions += list(elem.iter('ros2_control'))
    notes = Prepared(root_link=built.root_link, static=built.static,
                     joint_limits=dict(built.joint_limits), joint_links=dict(built.joint_links),
                     collisions=dict(built.collisions), extensions=extensions)
    notes.systems, notes.systems_not_run = _systems(elem, extensions[-1], built, world,
                                                    notes.repairs)
    notes.ros2_control = ros2_control.read(extensions)
    if notes.ros2_control is not None:
        notes.ros2_control = notes.ros2_control.with_speeds(notes.joint_limits)
    labels = {}
    chosen = {g for g, (how, _) in built.decompose.items() if how == 'convex_decomposition'}
    if chosen or (built.moving_joints == 0 and decompose.mode() != 'none') or \
            decompose.mode() == 'all':
        keep = {g for g, (how, _) in built.decompose.items() if how == 'convex_hull'}
        meshes = {g.meshname for g in spec.geoms if g.type == mujoco.mjtGeom.mjGEOM_MESH
                  and g.name not in keep and (g.name in chosen or built.moving_joints == 0
                                              or decompose.mode() == 'all')}
        if meshes:
            decompose.split_geoms(spec, labels, only=meshes, collisions=notes.collisions,
                                  max_parts=_most_hulls(spec, built.decompose))
    notes.declared, sensors = urdf_declared.add(
        spec, extensions, notes.joint_limits, notes.joint_links, notes.collisions)
    kinds = {(s.get('name') or ''): (s.get('type') or '').lower()
             for ext in extensions for s in ext.iter('sensor')}
    given = {s.get('name') or '' for ext in extensions for s in ext.iter('sensor')
             if any((s.findtext(t) or '').strip() for t in ('gz_frame_id', 'ign_frame_id'))
             or any((p.findtext(t) or '').strip() for p in s.iter('plugin')
                    for t in ('frame_name', 'frameName'))}
    notes.sensors = [own_frame(gz_streams(d, kinds), given) for d in sensors]
    notes.repairs = list(built.notes) + list(out.notes)
    decompose.bound_hulls(spec)
    return spec, notes


def _most_hulls(spec: mujoco.MjSpec, chosen: dict) -> dict:
    """Return mesh name -> SDF's ``<max_convex_hulls>`` of the collisions that set one."""
    out = {}
    for g in spec.geoms:
        how, most = chosen.get(g.name, ('', ''))
        if how == 'convex_decomposition' and most:
            out[g.meshname] = min(out.get(g.meshname, decompose.MAX_PARTS), int(most))
    return out


#: The last part of gz-sim's default topic of each sensor type.
_TOPIC_ENDS = {'camera': 'image', 'depth_camera': 'depth_image', 'depth': 'depth_image',
               'rgbd_camera': '', 'rgbd': '', 'gpu_lidar': 'scan', 'lidar': 'scan',
               'gpu_ray': 'scan', 'ray': 'scan', 'imu': 'imu', 'contact': 'contact',
               'force_torque': 'forcetorque', 'magnetometer': 'magnetometer',
               'navsat': 'navsat', 'gps': 'navsat'}


def gz_topics(world: str, model: str):
    """
    Return ``topics(link, sensor)``: a sensor's gz-sim default topic, where it names none.

    ``/world/<world>/model/<model>/link/<link>/sensor/<sensor>/<kind>`` (a joint's sensor:
    ``topics(joint, sensor, 'joint')``, ``.../joint/<joint>/sensor/...``; ``image``,
    ``depth_image``, ``scan``, ``imu``, ...; an RGB-D camera's streams below it), nested
    models' links scoped with ``/model/<nested>/link/...`` as gz-sim scopes them.
    """
    def topics(link: str, sensor: ET.Element, kind: str = 'link') -> str:
        *models, own = link.split('::')
        path = ''.join(f'/model/{m}' for m in [model] + models)
        end = _TOPIC_ENDS.get((sensor.get('type') or '').lower(), '')
        base = f'/world/{world}{path}/{kind}/{own}/sensor/{sensor.get("name") or "sensor"}'
        return f'{base}/{end}' if end else base
    return topics


def own_frame(decl, given: set):
    """
    Return a declared laser, IMU, magnetometer or NavSat in a frame of its own, as gz-sim's.

    gz-sim's sensors name their scoped name as their frame (``<model>::<link>::<sensor>``,
    ``<model>/<link>/<sensor>`` through ros_gz_bridge) unless ``<gz_frame_id>`` names one;
    here that frame is on /tf_static at the sensor's pose on its link (its scan or readings
    are where the sensor is, not at the link's origin). Those in `given` (a name of their
    own: ``gz_frame_id``, a plugin's ``frame_name``) keep it.
    """
    if not isinstance(decl, (DeclaredLaser, DeclaredImu, DeclaredGeo)):
        return decl
    name = decl.site[:decl.site.rindex('_')]
    if name in given:
        return decl
    return replace(decl, frame=f'{decl.frame}/{name}', own_frame=True)


def gz_streams(decl, kinds: dict):
    """
    Return a declared camera with its topics as gz-sim names them from its ``<topic>``.

    A ``camera``'s images on the topic itself, a ``depth_camera``'s depth images there (its
    points on ``<topic>/points``), an ``rgbd_camera``'s on ``<topic>/image``,
    ``<topic>/depth_image`` and ``<topic>/points``; the camera info beside the images
    (``<topic's folder>/camera_info``; an RGB-D camera's ``<topic>/camera_info``). Other
    sensors as they are.
    """
    if not isinstance(decl, DeclaredCamera) or not decl.topic:
        return decl
    t = decl.topic
    kind = kinds.get(decl.camera.rsplit('/', 1)[-1], 'camera')
    folder = t.rsplit('/', 1)[0] if '/' in t.strip('/') else ''
    info = f'{folder}/camera_info' if folder else 'camera_info'
    if kind in ('rgbd_camera', 'rgbd'):
        return replace(decl, image_topic=f'{t}/image', depth_topic=f'{t}/depth_image',
                       points_topic=f'{t}/points', info_topic=f'{t}/camera_info')
    if decl.depth:
        return replace(decl, image_topic=NO_TOPIC, depth_topic=t, points_topic=f'{t}/points',
                       info_topic=info)
    return replace(decl, image_topic=t, info_topic=info, depth_topic=NO_TOPIC)


def _systems(elem: ET.Element, plugins: ET.Element, built, world: str, said: list) -> tuple:
    """Return (the systems a model declares that are run here, those that are not)."""
    model, out = entity_name(elem.get('name', '')), []
    for plugin in plugins:
        kind = sdf_systems.system_name(plugin)
        try:
            system = sdf_systems.read(kind, plugin, model, built.joint_names,
                                      built.root_link.replace('/', '::'), world)
        except ValueError as exc:
            said.append(f'{exc}: the system is not run')
            continue
        if system is not None:
            out.append(system)
    return tuple(out), tuple(sdf_systems.model_systems(elem))


def _model_plugin(model: ET.Element, plugin: ET.Element) -> bool:
    """Whether `plugin` belongs to the model itself or a nested model (not to a sensor)."""
    return not any(plugin in list(s.iter('plugin')) for s in model.iter('sensor'))
