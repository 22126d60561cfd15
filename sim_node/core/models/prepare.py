"""
A model read from text made ready for MuJoCo before its spec is built and compiled.

URDF meshes of kinds MuJoCo cannot read converted (:mod:`.meshes`) and pointed at the result,
skin files inlined into the spec, a standalone MJCF model's loose ``<worldbody>`` geometry
gathered into one body of its own. Used by :mod:`.sources`; nothing here touches a live world.
"""

import logging
from pathlib import Path
import xml.etree.ElementTree as ET

import mujoco

from . import asset_store, assets, meshes
from ..base.errors import MissingAssetsError, ResourceParseError, UnsupportedAssetsError

log = logging.getLogger(__name__)

ERR_COMPILE = 'the model does not compile: {err}'
ERR_URDF_MESH_KIND = ('the mesh {value!r} is of a kind neither MuJoCo nor the converters read '
                      '({kind!r}): give an STL, OBJ, Collada (.dae), PLY, glTF or OFF file')


def compile_error(exc: Exception) -> Exception:
    """Return the error a failed compile of a model is refused with: a missing file, or not."""
    text = str(exc).strip()
    low = text.lower()
    if 'could not open' in low or 'error opening file' in low or 'resource not found' in low:
        return MissingAssetsError(ERR_COMPILE.format(err=text))
    return ResourceParseError(ERR_COMPILE.format(err=text))


def hold_if_stored(reader: assets.Reader, path: str) -> None:
    """Hold a conversion in the asset store (not one in the conversion cache, kept by design)."""
    if Path(path).parent == Path(asset_store.store().folder):
        reader.hold(path)


def convert_urdf_meshes(root: ET.Element, found: list, reader: assets.Reader) -> None:
    """
    Convert the URDF's meshes MuJoCo cannot read (:mod:`.meshes`); point them at the STL.

    A converted visual without a colour of its own takes the mesh file's (Collada materials).
    A file of a kind neither MuJoCo nor the converters read is refused (108), not compiled.
    """
    readable = assets.MUJOCO_MESH_SUFFIXES + meshes.CONVERTED_SUFFIXES
    for _, value, _ in found:
        kind = Path(value).suffix.lower()
        if kind not in readable:
            raise UnsupportedAssetsError(ERR_URDF_MESH_KIND.format(value=value, kind=kind))
    todo = [(elem, value, stored) for elem, value, stored in found
            if meshes.needs_conversion(value, stored)]
    if not todo:
        return
    done = meshes.convert([(value, stored) for _, value, stored in todo])
    visual_of = {id(m): v for v in root.iter('visual') for m in v.iter('mesh')}
    named = {m.get('name') for m in root.findall('material') if m.find('color') is not None}
    for (elem, value, _), converted in zip(todo, done):
        hold_if_stored(reader, converted.path)
        elem.set('filename', converted.path)
        if converted.decimated:
            log.warning('the mesh %s has %d faces, more than MuJoCo reads (%d): decimated to %d',
                        value, converted.faces_in, meshes.MUJOCO_MAX_FACES, converted.faces)
        visual = visual_of.get(id(elem))
        if visual is None or converted.rgba is None:
            continue
        material = visual.find('material')
        if material is not None and (material.find('color') is not None
                                     or material.get('name') in named):
            continue
        if material is None:
            material = ET.SubElement(visual, 'material')
        material.set('name', f'sim_mesh_colour_{len(named)}')
        named.add(material.get('name'))
        ET.SubElement(material, 'color', rgba=' '.join(f'{c:g}' for c in converted.rgba))


def inline_skin_files(spec: mujoco.MjSpec) -> None:
    """
    Put the content of skin files (``.skn``) into the spec itself.

    A skin file names its bones' bodies inside the file, read only at compile: attached under a
    prefix, with its root body renamed to the entity's name, the skin would look for a body
    that no longer exists. Inlined, the bone names are spec data that the attach prefixes and
    the rename repoints like every other reference. Costs one compile of the model alone, only
    for models with skin files (dm_control's dog).
    """
    skins = [sk for sk in spec.skins if sk.file]
    if not skins:
        return
    try:  # a copy: a compiled spec holds its processed meshes, slow to copy when attached
        m = spec.copy().compile()
    except ValueError as exc:
        raise compile_error(exc) from None
    for sk in skins:
        k = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SKIN, sk.name) if sk.name else -1
        k = k if k >= 0 else list(spec.skins).index(sk)
        va, vn = m.skin_vertadr[k], m.skin_vertnum[k]
        fa, fn = m.skin_faceadr[k], m.skin_facenum[k]
        ta = m.skin_texcoordadr[k]
        ba, bn = m.skin_boneadr[k], m.skin_bonenum[k]
        sk.file = ''
        sk.vert = m.skin_vert[va:va + vn].reshape(-1).tolist()
        sk.face = m.skin_face[fa:fa + fn].reshape(-1).tolist()
        sk.texcoord = (m.skin_texcoord[ta:ta + vn].reshape(-1).tolist() if ta >= 0 else [])
        sk.bodyname = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(b))
                       for b in m.skin_bonebodyid[ba:ba + bn]]
        sk.bindpos = m.skin_bonebindpos[ba:ba + bn].reshape(-1).tolist()
        sk.bindquat = m.skin_bonebindquat[ba:ba + bn].reshape(-1).tolist()
        vertid, vertweight = [], []
        for b in range(ba, ba + bn):
            adr, num = m.skin_bonevertadr[b], m.skin_bonevertnum[b]
            vertid.append(m.skin_bonevertid[adr:adr + num].tolist())
            vertweight.append(m.skin_bonevertweight[adr:adr + num].tolist())
        sk.vertid, sk.vertweight = vertid, vertweight


#: The body that a standalone model's static <worldbody> geoms and sites are gathered into.
WORLD_GEOMS_BODY = 'world_geoms'


def gather_world_geoms(root: ET.Element) -> None:
    """
    Gather a standalone model's static geometry into one welded body of the model.

    Geoms and sites directly in <worldbody> (not ground planes, which the world drops when it
    attaches the model) move into one welded body, appended after the model's own top-level
    bodies, so they become part of the entity. Nothing changes when there is nothing to gather.
    """
    wb = root.find('worldbody')
    loose = [] if wb is None else [e for e in wb if e.tag in ('geom', 'site')
                                   and e.get('type') != 'plane']
    if not loose:
        return
    taken = {e.get('name') for e in root.iter('body')}
    name, i = WORLD_GEOMS_BODY, 0
    while name in taken:
        i += 1
        name = f'{WORLD_GEOMS_BODY}_{i}'
    holder = ET.SubElement(wb, 'body', name=name)
    for e in loose:
        wb.remove(e)
        holder.append(e)
