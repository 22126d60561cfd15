"""
Every SDF element this simulator meets, and what it makes of it: read, approximated or ignored.

:data:`TABLE` is the one place that says it, by parent element: ``read`` (as Gazebo means it),
``approximated`` (read, made as near as MuJoCo allows: how is said), ``ignored`` (no meaning in
this simulator: a GUI's layout, an engine's own tuning knob; accepted silently), or
``unsupported`` (it means something for a simulation and is not reproduced). An element whose
parent the table knows but that it does not list is unsupported too (an unknown tag).
:func:`not_read` walks a document and names what is unsupported (``LoadWorld``'s
``fail_on_unsupported_element`` refuses a world that has any; otherwise they are listed in the
answer and the log); :func:`markdown` prints the table docs/sdf.md holds (a test keeps the two
the same). A sensor's and a plugin's insides are theirs: a sensor's tags are read by
:mod:`.sensor_tags`, a plugin's by the system it names (:mod:`.sdf_systems`).
"""

from typing import Optional
import xml.etree.ElementTree as ET

READ, APPROXIMATED, IGNORED, UNSUPPORTED = 'read', 'approximated', 'ignored', 'unsupported'
_R, _A, _I, _U = READ, APPROXIMATED, IGNORED, UNSUPPORTED

#: parent -> {child: (status, how)}; '*' children of a parent are not walked (opaque).
TABLE = {
    'sdf': {
        'world': (_R, 'one world per file (the first)'),
        'model': (_R, 'spawned as one entity, or a world of it'),
        'light': (_R, 'in an included file: a light of the world'),
        'actor': (_U, 'animated people are not simulated'),
    },
    'world': {
        'model': (_R, 'each top-level model an entity, named by it'),
        'include': (_R, 'model://, Fuel, relative and absolute URIs; name, pose, static, '
                        'placement_frame and plugins overridden'),
        'frame': (_R, 'for poses relative to it'),
        'light': (_R, 'MuJoCo lights (at most 8 are drawn)'),
        'physics': (_R, ''), 'gravity': (_R, 'option gravity'),
        'magnetic_field': (_R, "option magnetic (magnetometers read it; SDF's default "
                               'where absent)'),
        'scene': (_R, ''), 'spherical_coordinates': (_R, 'WGS84, ENU: where NavSat receivers '
                                                         'are on the Earth'),
        'plugin': (_R, 'systems: see the systems table'),
        'atmosphere': (_A, 'MuJoCo has no air by default, as Gazebo applies no drag'),
        'wind': (_A, 'not applied (links do not feel wind)'),
        'gui': (_I, ''), 'audio': (_I, ''), 'state': (_A, 'not applied: the models start '
                                                          'where the world file puts them'),
        'population': (_U, 'not expanded'), 'road': (_U, ''), 'actor': (_U, ''),
        'joint': (_U, 'joints between world models'), 'particle_emitter': (_U, ''),
        'enable_wind': (_I, ''), 'atmosphere_model': (_I, ''),
    },
    'physics': {
        'max_step_size': (_R, 'the timestep'),
        'real_time_factor': (_R, 'the pace, unless the node was given its own'),
        'real_time_update_rate': (_I, 'the loop steps as the factor asks'),
        'max_contacts': (_I, ''), 'ode': (_R, ''), 'bullet': (_R, ''), 'dart': (_I, ''),
        'simbody': (_I, ''), 'gravity': (_R, 'SDF 1.5 and older'),
        'magnetic_field': (_R, 'SDF 1.5 and older'),
    },
    'ode': {
        'solver': (_R, ''), 'constraints': (_A, "MuJoCo's own soft contacts"),
        'iters': (_R, ''), 'type': (_I, ''), 'min_step_size': (_I, ''),
        'precon_iters': (_I, ''), 'sor': (_I, ''), 'use_dynamic_moi_rescaling': (_I, ''),
        'friction_model': (_I, ''), 'island_threads': (_I, ''),
        'thread_position_correction': (_I, ''),
        'mu': (_R, ''), 'mu2': (_A, 'friction is isotropic: mu'), 'fdir1': (_A, 'isotropic'),
        'slip1': (_I, ''), 'slip2': (_I, ''),
        'kp': (_A, "MuJoCo's direct stiffness per unit of the link mass"),
        'kd': (_A, 'direct damping per unit of the link mass'), 'soft_cfm': (_I, ''),
        'soft_erp': (_I, ''), 'max_vel': (_I, ''), 'min_depth': (_I, ''),
        'cfm': (_I, ''), 'erp': (_I, ''), 'contact_max_correcting_vel': (_I, ''),
        'contact_surface_layer': (_I, ''),
    },
    'solver': {'iters': (_R, "MuJoCo's most solver iterations"), 'type': (_I, ''),
               'min_step_size': (_I, ''), 'precon_iters': (_I, ''), 'sor': (_I, ''),
               'use_dynamic_moi_rescaling': (_I, ''), 'friction_model': (_I, ''),
               'island_threads': (_I, ''), 'thread_position_correction': (_I, ''),
               'split_impulse': (_I, ''), 'split_impulse_penetration_threshold': (_I, '')},
    'bullet': {'solver': (_R, ''), 'constraints': (_A, "MuJoCo's own"),
               'friction': (_R, 'the sliding friction'), 'friction2': (_A, 'isotropic'),
               'fdir1': (_A, 'isotropic'), 'rolling_friction': (_I, ''),
               'kp': (_A, ''), 'kd': (_A, ''), 'soft_cfm': (_I, ''), 'soft_erp': (_I, ''),
               'split_impulse': (_I, ''), 'split_impulse_penetration_threshold': (_I, '')},
    'scene': {'ambient': (_R, 'the headlight'), 'background': (_R, 'the sky colour'),
              'sky': (_A, 'a gradient sky'), 'shadows': (_I, ''), 'grid': (_I, ''),
              'origin_visual': (_I, ''), 'fog': (_I, '')},
    'model': {
        'link': (_R, 'a body'), 'joint': (_R, ''),
        'model': (_R, 'nested: flattened into its top model'),
        'include': (_R, 'as in a world; merge="true" too'), 'frame': (_R, ''),
        'pose': (_R, 'relative_to, placement_frame, degrees, quat_xyzw'),
        'static': (_R, 'every link welded'), 'self_collide': (_R, ''),
        'plugin': (_R, 'systems: see the systems table'),
        'allow_auto_disable': (_I, ''), 'enable_wind': (_I, ''), 'gripper': (_U, ''),
        'ros2_control': (_R, 'as a URDF block'),
    },
    'link': {
        'inertial': (_R, 'mass, pose, inertia; auto from collisions (1.11)'),
        'collision': (_R, ''), 'visual': (_R, ''), 'sensor': (_R, 'see the sensors table'),
        'light': (_R, 'a light of the body'), 'pose': (_R, ''),
        'gravity': (_R, 'false: compensated against gravity'),
        'self_collide': (_R, ''), 'kinematic': (_A, 'moves by physics all the same'),
        'enable_wind': (_I, ''), 'must_be_base_link': (_I, ''),
        'velocity_decay': (_A, 'not applied'), 'projector': (_U, ''),
        'audio_sink': (_I, ''), 'audio_source': (_I, ''), 'battery': (_U, ''),
        'particle_emitter': (_U, ''), 'visualize': (_I, ''),
    },
    'inertial': {'mass': (_R, ''), 'pose': (_R, ''),
                 'inertia': (_R, 'repaired where MuJoCo refuses it'),
                 'fluid_added_mass': (_U, ''), 'density': (_R, ''),
                 'auto_inertia_params': (_I, '')},
    'joint': {
        'parent': (_R, ''), 'child': (_R, ''), 'pose': (_R, ''), 'axis': (_R, ''),
        'axis2': (_R, ''), 'thread_pitch': (_R, ''), 'screw_thread_pitch': (_R, ''),
        'gearbox_ratio': (_A, 'a gearbox turns as a revolute joint'),
        'gearbox_reference_body': (_A, ''), 'physics': (_I, ''),
        'sensor': (_R, 'force_torque (see the sensors table)'),
    },
    'axis': {'xyz': (_R, 'expressed_in; use_parent_model_frame'), 'limit': (_R, ''),
             'dynamics': (_R, ''), 'use_parent_model_frame': (_R, ''), 'initial_position':
             (_U, ''), 'mimic': (_R, 'a joint equality')},
    'limit': {'lower': (_R, ''), 'upper': (_R, ''), 'effort': (_R, 'the joint actuator force '
                                                                   'range'),
              'velocity': (_R, "its controllers' limit"),
              'stiffness': (_A, "MuJoCo's limit softness"),
              'dissipation': (_A, "MuJoCo's limit softness")},
    'dynamics': {'damping': (_R, ''), 'friction': (_R, 'frictionloss'),
                 'spring_reference': (_R, ''), 'spring_stiffness': (_R, '')},
    'mimic': {'multiplier': (_R, ''), 'offset': (_R, ''), 'reference': (_R, '')},
    'collision': {'geometry': (_R, ''), 'pose': (_R, ''), 'surface': (_R, ''),
                  'laser_retro': (_I, ''), 'max_contacts': (_I, ''), 'density': (_R, ''),
                  'auto_inertia_params': (_I, '')},
    'visual': {'geometry': (_R, ''), 'pose': (_R, ''), 'material': (_R, ''),
               'transparency': (_R, 'alpha'), 'cast_shadows': (_I, ''), 'laser_retro': (_I, ''),
               'meta': (_I, ''), 'visibility_flags': (_I, ''), 'plugin': (_I, '')},
    'geometry': {'box': (_R, ''), 'sphere': (_R, ''), 'cylinder': (_R, ''),
                 'capsule': (_R, ''), 'ellipsoid': (_R, ''), 'plane': (_R, 'infinite for '
                                                                           'contacts'),
                 'mesh': (_R, 'STL, OBJ; Collada, glTF, PLY, OFF converted'),
                 'polyline': (_R, 'extruded into a mesh'), 'cone': (_R, 'a mesh'),
                 'heightmap': (_A, 'a height field from a PNG; no textures or blends'),
                 'image': (_U, ''), 'empty': (_R, '')},
    'mesh': {'uri': (_R, ''), 'scale': (_R, ''),
             'submesh': (_A, 'the whole mesh file is drawn'),
             'convex_decomposition': (_R, 'CoACD, max_convex_hulls parts at most')},
    'surface': {'friction': (_R, ''), 'bounce': (_R, ''), 'contact': (_R, ''),
                'soft_contact': (_I, '')},
    'friction': {'ode': (_R, ''), 'bullet': (_R, ''), 'torsional': (_R, ''),
                 'simbody': (_I, '')},
    'torsional': {'coefficient': (_R, ''), 'patch_radius': (_R, ''),
                  'surface_radius': (_I, ''), 'use_patch_radius': (_I, ''), 'ode': (_I, '')},
    'bounce': {'restitution_coefficient': (_R, ''), 'threshold': (_I, '')},
    'contact': {'collide_bitmask': (_R, ''), 'category_bitmask': (_R, ''),
                'collide_without_contact': (_U, ''), 'collide_without_contact_bitmask':
                (_U, ''), 'poissons_ratio': (_I, ''), 'elastic_modulus': (_I, ''),
                'ode': (_R, ''), 'bullet': (_R, ''), 'opensim': (_I, ''),
                'simbody': (_I, '')},
    'material': {'diffuse': (_R, ''), 'ambient': (_R, 'where no diffuse'),
                 'specular': (_R, ''), 'emissive': (_R, ''),
                 'script': (_A, "Gazebo's named colours"), 'pbr': (_A, 'its albedo map'),
                 'lighting': (_I, ''), 'shader': (_I, ''), 'render_order': (_I, ''),
                 'double_sided': (_I, '')},
    'light': {'pose': (_R, ''), 'diffuse': (_R, ''), 'specular': (_R, ''),
              'attenuation': (_R, ''), 'direction': (_R, ''), 'spot': (_R, ''),
              'cast_shadows': (_R, ''), 'intensity': (_I, ''), 'visualize': (_I, ''),
              'light_on': (_I, '')},
    'frame': {'pose': (_R, '')},
    'include': {'uri': (_R, ''), 'name': (_R, ''), 'pose': (_R, ''), 'static': (_R, ''),
                'placement_frame': (_R, ''), 'plugin': (_R, '')},
}
#: Subtrees read by the element they belong to, not walked here.
OPAQUE = ('sensor', 'plugin', 'ros2_control', 'gui', 'atmosphere', 'spherical_coordinates',
          'wind', 'state', 'audio', 'population', 'road', 'actor', 'heightmap', 'polyline',
          'cone', 'box', 'sphere', 'cylinder', 'capsule', 'ellipsoid', 'plane', 'image',
          'inertia', 'xyz', 'pbr', 'script', 'spot', 'attenuation', 'pose', 'uri', 'name',
          'solver', 'constraints', 'sky', 'meta', 'visibility_flags', 'physics')
#: Attributes the reader itself puts on elements (not part of SDF).
_TAGS = ('sim:folder', 'sim:version', 'sim:urdf')


def status(parent: str, child: str, under: Optional[str] = None) -> tuple:
    """Return (status, how) of `child` inside `parent` (``under``: the parent's parent)."""
    table = TABLE.get(parent)
    if parent in ('ode', 'bullet') and under in ('friction', 'contact', 'physics', 'torsional'):
        table = {**TABLE['ode'], **TABLE['bullet']}
    if parent == 'contact' and under == 'sensor':
        return _R, ''
    if table is None:
        return _R, ''
    return table.get(child, (_U, 'not an element this simulator knows here'))


def not_read(root: ET.Element) -> list:
    """Return the ``parent/child`` paths of every unsupported element below `root`, sorted."""
    found = set()
    stack = [(root, None)]
    said: dict = {}  # (parent, child, grandparent) -> status: a world repeats few of them
    while stack:
        elem, under = stack.pop()
        if elem.tag in OPAQUE:
            continue
        for child in elem:
            if not isinstance(child.tag, str):
                continue
            tag = child.tag.split('}')[-1]
            if ':' in tag:  # <gz:...>, <ignition:...> extension elements: said apart
                found.add(f'{elem.tag}/{tag}')
                continue
            key = (elem.tag, tag, under)
            state = said.get(key)
            if state is None:
                state = said[key] = status(elem.tag, tag, under)[0]
            if state == UNSUPPORTED:
                found.add(f'{elem.tag}/{tag}')
            elif state in (READ, APPROXIMATED):
                stack.append((child, elem.tag))
    return sorted(found)


def markdown() -> str:
    """Return the element table as docs/sdf.md holds it (one row per element)."""
    rows = ['| element | in | status | how |', '|---|---|---|---|']
    for parent, children in TABLE.items():
        for child, (state, how) in sorted(children.items()):
            rows.append(f'| `<{child}>` | `<{parent}>` | {state} | {how} |')
    return '\n'.join(rows) + '\n'
