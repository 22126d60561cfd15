"""
What a model can see and feel: its cameras, sites and sensors, indexed once per recompile.

Sensors are grouped as ROS publishes them: on one site, a ``framequat``, ``gyro`` and
``accelerometer`` make one IMU and a ``force`` and ``torque`` one wrench; a ``rangefinder`` is
a range; every other sensor is generic (its values as MuJoCo gives them).
"""

import mujoco

from ..base.records import CameraSpec, SensorSpec, SiteSpec

_SITE = int(mujoco.mjtObj.mjOBJ_SITE)
_FIXED = int(mujoco.mjtCamLight.mjCAMLIGHT_FIXED)
_PERSPECTIVE = int(mujoco.mjtProjection.mjPROJ_PERSPECTIVE)
_S = mujoco.mjtSensor
IMU_PARTS = {int(_S.mjSENS_FRAMEQUAT): 'quat', int(_S.mjSENS_GYRO): 'gyro',
             int(_S.mjSENS_ACCELEROMETER): 'accelerometer'}
WRENCH_PARTS = {int(_S.mjSENS_FORCE): 'force', int(_S.mjSENS_TORQUE): 'torque'}
_RANGE = int(_S.mjSENS_RANGEFINDER)


def _name(m: mujoco.MjModel, obj: mujoco.mjtObj, i: int) -> str:
    return mujoco.mj_id2name(m, obj, i) or ''


def cameras(m: mujoco.MjModel) -> tuple:
    """Return a :class:`CameraSpec` per camera of `m`, in model order."""
    return tuple(CameraSpec(
        name=_name(m, mujoco.mjtObj.mjOBJ_CAMERA, c) or f'camera{c}', cam_id=c,
        body=int(m.cam_bodyid[c]), pos=tuple(float(x) for x in m.cam_pos[c]),
        quat_wxyz=tuple(float(x) for x in m.cam_quat[c]), fovy_deg=float(m.cam_fovy[c]),
        fixed=int(m.cam_mode[c]) == _FIXED, orthographic=int(m.cam_projection[c]) != _PERSPECTIVE)
        for c in range(m.ncam))


def sites(m: mujoco.MjModel) -> tuple:
    """Return a :class:`SiteSpec` per named site of `m`."""
    out = []
    for s in range(m.nsite):
        name = _name(m, mujoco.mjtObj.mjOBJ_SITE, s)
        if name:
            out.append(_site(m, s, name))
    return tuple(out)


def _site(m: mujoco.MjModel, s: int, name: str = '') -> SiteSpec:
    return SiteSpec(name=name or _name(m, mujoco.mjtObj.mjOBJ_SITE, s) or f'site{s}',
                    site_id=s, body=int(m.site_bodyid[s]),
                    pos=tuple(float(x) for x in m.site_pos[s]),
                    quat_wxyz=tuple(float(x) for x in m.site_quat[s]))


def _type_name(t: int) -> str:
    return mujoco.mjtSensor(t).name[len('mjSENS_'):].lower()


def sensors(m: mujoco.MjModel) -> tuple:
    """Group the sensors of `m` into :class:`SensorSpec` (see the module's docstring)."""
    imus, wrenches, out = {}, {}, []
    for i in range(m.nsensor):
        t, obj = int(m.sensor_type[i]), int(m.sensor_objid[i])
        on_site = int(m.sensor_objtype[i]) == _SITE
        adr = (int(m.sensor_adr[i]), int(m.sensor_dim[i]))
        name = _name(m, mujoco.mjtObj.mjOBJ_SENSOR, i) or f'sensor{i}'
        if on_site and t in IMU_PARTS and IMU_PARTS[t] not in imus.get(obj, {}):
            imus.setdefault(obj, {})[IMU_PARTS[t]] = adr
        elif on_site and t in WRENCH_PARTS and WRENCH_PARTS[t] not in wrenches.get(obj, {}):
            wrenches.setdefault(obj, {})[WRENCH_PARTS[t]] = adr
        elif t == _RANGE and on_site:
            out.append(SensorSpec(kind='range', name=name, adr={'value': adr},
                                  site=_site(m, obj), cutoff=float(m.sensor_cutoff[i]),
                                  type_name='rangefinder'))
        else:
            out.append(SensorSpec(kind='generic', name=name, adr={'value': adr},
                                  type_name=_type_name(t)))
    for kind, groups in (('imu', imus), ('wrench', wrenches)):
        for s, parts in groups.items():
            site = _site(m, s)
            out.append(SensorSpec(kind=kind, name=site.name, adr=parts, site=site,
                                  type_name=kind))
    return tuple(out)
