"""
Sensors sampled in the stepping loop at their own rates of simulated time: IMUs and contacts.

A robot file's IMU says how often it samples (``update_rate``, :class:`~..records.DeclaredImu`).
Snapshots come at a wall-clock rate, too seldom for a 250 Hz IMU and never in step with
simulated time; so the loop stops its batch of steps at each due time (as it does for a base's
timeout, :mod:`.steps`) and copies the IMU's values, with its Gaussian noise (seeded by the
site's name: a run repeats), into a queue that the node drains and publishes, each sample
stamped with its own simulated time. A time that goes back (a reset) starts the schedule over.

Contact sensors (:class:`~..records.DeclaredContact`: declared, MuJoCo's, and the entities
whose contacts were asked for, :class:`ContactRequest`) are sampled the same way, each a
:class:`~..devices.contacts.ContactReport` in the same queue.

P3D plugins' ground truth is too (:mod:`.odometers`), and magnetometers and NavSat receivers
(:mod:`.geo`).

Laser scanners are too (:func:`laser_requests`), in two halves: at each due time the stepping
side keeps where the world was (a :class:`LaserPose`), and the perception side casts the rays
later against it, off the stepping thread and without the world lock
(:meth:`~..lidar.LaserScanner.cast`). A scan is then never left out when the perception side
is late (a camera being drawn, cores short), and it is stamped with its own due time, at any
real-time factor. A laser's due time ends no batch of steps: a batch with one inside is
stepped by MuJoCo's rollout, which gives the state after every step, and the pose is the
state then (:meth:`Sampler.roll`; the perception side works out where the geoms were). Each
MuJoCo call gives the GIL away and the loop waits to get it back, and at real_time_factor 0 a
laser is due hundreds of times a wall second. Stepped one step at a time (a command applied
before every step), the loop copies the poses the step from the due time computed
(:func:`pose_lag`).
"""

from collections import deque
import logging
import math
import time
from typing import Callable, NamedTuple, Optional
import zlib

import mujoco
from mujoco import rollout
import numpy as np

from . import geo, odometers
from ..base.errors import InvalidArgumentError
from ..devices import contacts

log = logging.getLogger(__name__)

#: Samples kept for the node between two drains (a slow consumer loses the oldest).
SAMPLES_KEPT = 10_000
#: The most contact reports per simulated second.
MAX_CONTACT_RATE_HZ = 1000.0
#: The most joint samples per simulated second (a controller manager's update rate).
MAX_JOINT_RATE_HZ = 10_000.0
#: Joint samples of one request come at most this many per wall second, in bursts of at most
#: JOINT_BURST (a token bucket): a 1 kHz controller manager's pace in real time. Faster than
#: real time the loop has more due than anyone can use, and each costs the loop; a sample left
#: out leaves a longer gap in simulated time before the next.
MAX_JOINT_WALL_HZ = 1000.0
JOINT_BURST = 50
#: Simulated time within this fraction of a period of a due time counts as due.
DUE_TOLERANCE = 1e-6
#: Laser poses kept for the perception side between two drains (a slow one loses the oldest:
#: each holds every geom's pose, 96 bytes a geom).
LASER_POSES_KEPT = 64
#: The most scans per simulated second of one laser.
MAX_LASER_RATE_HZ = 1000.0


class _Entry:
    __slots__ = ('site', 'period', 'quat', 'gyro', 'acc', 'gyro_noise', 'acc_noise', 'rng',
                 'next')

    def __init__(self, site: str, period: float, adr: dict, decl):
        self.site, self.period = site, period
        parts = ('quat', 'gyro', 'accelerometer')
        self.quat, self.gyro, self.acc = (_slice(adr.get(k)) for k in parts)
        self.gyro_noise, self.acc_noise = decl.gyro_noise, decl.accel_noise
        self.rng = np.random.default_rng(zlib.crc32(site.encode()))
        self.next = math.nan


class ContactRequest(NamedTuple):
    """Entities whose contacts are reported, and how often (simulated Hz)."""

    entities: tuple = ()
    rate_hz: float = 50.0


class JointSample(NamedTuple):
    """Joints' positions, velocities and actuator efforts at one simulated time."""

    key: str
    time: float
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray
    generation: int = 0
    sensordata: Optional[np.ndarray] = None  # MuJoCo's sensor values then, if asked for
    resets: int = 0  # the world's resets of state before it (Clock.resets)


class _Joints:
    __slots__ = ('name', 'period', 'qpos', 'dof', 'sensors', 'tick', 'next', 'tokens', 'wall')

    def __init__(self, name: str, period: float, qpos: np.ndarray, dof: np.ndarray,
                 sensors: bool, tick: Optional[Callable]):
        self.name, self.period, self.qpos, self.dof = name, period, qpos, dof
        self.sensors, self.tick = sensors, tick
        self.next = math.nan
        self.tokens, self.wall = float(JOINT_BURST), time.perf_counter()  # a token bucket


class LaserPose(NamedTuple):
    """Where a laser and every geom were at one simulated time: its rays are cast later."""

    site: str
    time: float
    generation: int
    resets: int  # the world's resets of state before it (stale after another)
    origin: np.ndarray  # (3,) the site's position in the world
    frame: np.ndarray  # (3, 3) the site's orientation in the world
    # What MuJoCo's ray casting reads of the data (mj_multiRay culls by each body's inertial
    # frame first), shared by the lasers due at the same time:
    geom_xpos: np.ndarray  # (ngeom, 3)
    geom_xmat: np.ndarray  # (ngeom, 9)
    xipos: np.ndarray  # (nbody, 3)
    ximat: np.ndarray  # (nbody, 9)
    flexvert_xpos: np.ndarray  # (nflexvert, 3)
    #: Or, for a pose taken within a batch stepped by rollout (:meth:`Sampler.roll`): the
    #: state then (mjSTATE_FULLPHYSICS), the rest above None, worked out where it is cast.
    state: Optional[np.ndarray] = None


class _Laser:
    __slots__ = ('name', 'site', 'period', 'next')

    def __init__(self, name: str, site: int, period: float):
        self.name, self.site, self.period = name, site, period
        self.next = math.nan


class _Contacts:
    __slots__ = ('name', 'period', 'mine', 'others', 'next')

    def __init__(self, name: str, period: float, mine: np.ndarray,
                 others: Optional[np.ndarray]):
        self.name, self.period, self.mine, self.others = name, period, mine, others
        self.next = math.nan


def _mask(n: int, ids) -> np.ndarray:
    out = np.zeros(n, bool)
    out[list(ids)] = True
    return out


def _slice(adr: Optional[tuple]) -> Optional[slice]:
    return None if adr is None else slice(adr[0], adr[0] + adr[1])


class Sampler:
    """
    The declared IMUs of one model generation, sampled as the loop steps.

    :param info: the generation's :class:`~..records.ModelInfo` (its ``imus`` and the IMU
        sensor groups they are, its ``contacts`` and ``geom_scoped``).
    :param request: the entities whose contacts were asked for (their reports are named as
        the entity), and the rate of those and of contact sensors that declare none.
    :param joints: (key, joint names, rate Hz, with sensor values, tick) of each set of joints
        sampled as a :class:`JointSample` (a controller manager's, at its update rate); a
        tick (None, or a callable) takes every sample due, those the queue leaves out
        included, and returns joint commands ((names, values, mode) each): they are in
        :attr:`writes` after :meth:`collect`, for the stepping side to apply before the next
        step.
    :param lasers: (site name, rate Hz) of each laser whose pose is taken into `poses` as a
        :class:`LaserPose` at each due time (:func:`laser_requests`).
    """

    def __init__(self, index, samples: deque, request: ContactRequest = ContactRequest(),
                 joints: tuple = (), resets: int = 0, lasers: tuple = (),
                 poses: Optional[deque] = None):
        info = index.info
        self.generation, self.request, self.joints = info.generation, request, joints
        self.resets, self.lasers = resets, lasers
        site_ids = {s.name: s.site_id for s in info.sites}
        self._lasers = [_Laser(name, site_ids[name], 1.0 / rate) for name, rate in lasers
                        if name in site_ids]
        self._poses = poses if poses is not None else new_laser_queue()
        self._entries = [_Entry(s.name, 1.0 / info.imus[s.name].rate_hz, s.adr,
                                info.imus[s.name])
                         for s in info.sensors if s.kind == 'imu' and s.name in info.imus]
        ngeom = len(info.geom_scoped)
        self._contacts = [
            _Contacts(c.name, 1.0 / (c.rate_hz or request.rate_hz), _mask(ngeom, c.geoms),
                      _mask(ngeom, c.others) if c.others else None)
            for c in info.contacts.values()]
        roots = {e.name: e.root_body for e in info.entities}
        self._contacts += [
            _Contacts(name, 1.0 / request.rate_hz,
                      info.body_root[info.geom_body] == roots[name], None)
            for name in request.entities if name in roots and name not in info.contacts]
        self._odometers = odometers.entries(info)
        self._geo = geo.entries(info)
        self._joints = []
        for key, names, rate, sensors, tick in joints:
            idx = [index.joint_index[n] for n in names if n in index.joint_index]
            if idx and len(idx) == len(names):
                self._joints.append(_Joints(key, 1.0 / rate, index.joint_qposadr[idx],
                                            index.joint_dofadr[idx], sensors, tick))
        self.writes: list = []  # the ticks' joint commands of the last collect
        self._timed = self._entries + self._contacts + self._joints + self._odometers + \
            self._geo  # due at their times (a laser: see next_due)
        self._all = self._timed + self._lasers
        self._samples = samples
        self._last = -math.inf

    def __bool__(self) -> bool:
        return bool(self._all)

    def next_due(self, now: float) -> float:
        """
        Return the earliest simulated time at or after `now` a sample is due.

        A laser's due time is not one: it ends no batch, :meth:`roll` takes it within.
        """
        if now < self._last:  # a reset: every schedule starts over
            for e in self._all:
                e.next = math.nan
        self._last = now
        for e in self._all:
            if math.isnan(e.next):
                e.next = now
        return min((e.next for e in self._timed), default=math.inf)

    def lasers_due_by(self, end: float) -> bool:
        """Whether a laser is due at or before simulated time `end`."""
        return any(not end < la.next - DUE_TOLERANCE * la.period for la in self._lasers)

    def roll(self, m: mujoco.MjModel, d: mujoco.MjData, k: int) -> None:
        """
        Step `k` times as ``mj_step`` does, taking the state at each laser's due time within.

        MuJoCo's rollout steps the data and writes the state after every step, all in one
        call that gives the GIL away once: at real_time_factor 0 a laser is due hundreds of
        times a wall second, and a batch ended at each (:func:`pose_lag`) made the loop wait
        for the GIL back each time from whichever thread took it (the mobile scene's laser:
        0.92x bare MuJoCo, 0.81x recording, ``make bench-bases``). With the data's own state
        and warm start the steps are the same bit for bit. A due time between two steps
        takes the state at the first step at or after it, stamped with that state's time,
        as a batch ended there would.
        """
        full = mujoco.mjtState.mjSTATE_FULLPHYSICS
        start = np.empty((1, mujoco.mj_stateSize(m, full)))
        mujoco.mj_getState(m, d, start[0], full)
        states = np.empty((1, k, start.shape[1]))
        rollout.rollout([m], [d], start, None, nstep=k, skip_checks=True,
                        initial_warmstart=d.qacc_warmstart.reshape(1, -1).copy(),
                        state=states, sensordata=np.empty((1, k, m.nsensordata)))
        t0, dt = float(start[0, 0]), float(m.opt.timestep)
        taken = []
        for la in self._lasers:
            while True:
                j = max(0, math.ceil((la.next - t0) / dt - 1e-6))
                if j > k:
                    break
                row = start[0] if j == 0 else states[0, j - 1]
                t = float(row[0])
                taken.append(LaserPose(la.name, t, self.generation, self.resets, None, None,
                                       None, None, None, None, None, row.copy()))
                la.next = (math.floor(t / la.period + DUE_TOLERANCE) + 1) * la.period
        self._poses.extend(sorted(taken, key=lambda p: p.time))

    def collect(self, m: mujoco.MjModel, d: mujoco.MjData, lasers: bool = True) -> None:
        """
        Take the samples due at the data's time (after a step ended there).

        A schedule not started yet (or started over by a reset: time went back) is due now.
        :param lasers: False after :meth:`roll`, which took the lasers' already.
        """
        t = float(d.time)
        if t < self._last:
            for e in self._all:
                e.next = math.nan
        self._last = t
        for j in self._joints:
            if t < j.next - DUE_TOLERANCE * j.period:  # (NaN: due now)
                continue
            now = time.perf_counter()
            j.tokens = min(JOINT_BURST, j.tokens + (now - j.wall) * MAX_JOINT_WALL_HZ)
            j.wall = now
            j.next = (math.floor(t / j.period + DUE_TOLERANCE) + 1) * j.period
            queued = j.tokens >= 1.0  # else faster than real time: left out of the queue
            if not queued and j.tick is None:
                continue
            sample = JointSample(
                j.name, t, d.qpos[j.qpos], d.qvel[j.dof], d.qfrc_actuator[j.dof],
                self.generation, d.sensordata.copy() if j.sensors and queued else None,
                self.resets)
            if j.tick is not None:
                try:
                    self.writes += j.tick(sample)
                except Exception:  # noqa: B902 (the world steps on; the tick's owner reports)
                    log.exception('joint sample tick %s failed', j.name)
            if queued:
                j.tokens -= 1.0
                self._samples.append(sample)
        for c in self._contacts:
            if t < c.next - DUE_TOLERANCE * c.period:  # (NaN: due now)
                continue
            self._samples.append(contacts.ContactReport(
                c.name, t, contacts.read(m, d, c.mine, c.others), self.generation))
            c.next = (math.floor(t / c.period + DUE_TOLERANCE) + 1) * c.period
        for e in self._entries:
            if t < e.next - DUE_TOLERANCE * e.period:  # (NaN: due now)
                continue
            data = d.sensordata
            quat = data[e.quat].copy() if e.quat is not None else None
            gyro = data[e.gyro].copy() if e.gyro is not None else None
            acc = data[e.acc].copy() if e.acc is not None else None
            if gyro is not None and e.gyro_noise is not None:
                gyro += e.rng.normal(e.gyro_noise[0], e.gyro_noise[1])
            if acc is not None and e.acc_noise is not None:
                acc += e.rng.normal(e.acc_noise[0], e.acc_noise[1])
            self._samples.append((e.site, t, quat, gyro, acc))
            e.next = (math.floor(t / e.period + DUE_TOLERANCE) + 1) * e.period
        # After a step, the data's poses are those of the state before it (pose_lag): the
        # lasers take them as they are, stamped with that time, before anything below brings
        # them up to date (once for all that are due: velocities too, for the odometers).
        if self._lasers and lasers:
            lag = pose_lag(m)
            before = t - lag
            due = [la for la in self._lasers
                   if not before < la.next - DUE_TOLERANCE * la.period]
            if due and not lag:
                mujoco.mj_kinematics(m, d)
            if due:
                self._take_poses(d, before, due)
        odo = [o for o in self._odometers if not t < o.next - DUE_TOLERANCE * o.period]
        places = [g for g in self._geo if not t < g.next - DUE_TOLERANCE * g.period]
        if odo:
            odometers.bring_up_to_date(m, d)
        elif places:
            mujoco.mj_kinematics(m, d)
        for o in odo + places:
            self._samples.append(o.take(m, d, t, self.generation))
            o.next = (math.floor(t / o.period + DUE_TOLERANCE) + 1) * o.period

    def _take_poses(self, d: mujoco.MjData, t: float, due: list) -> None:
        """Copy where the due lasers and every geom are in the data: their poses at `t`."""
        where = (d.geom_xpos.copy(), d.geom_xmat.copy(), d.xipos.copy(), d.ximat.copy(),
                 d.flexvert_xpos.copy())
        for la in due:
            self._poses.append(LaserPose(
                la.name, t, self.generation, self.resets, d.site_xpos[la.site].copy(),
                d.site_xmat[la.site].reshape(3, 3).copy(), *where))
            la.next = (math.floor(t / la.period + DUE_TOLERANCE) + 1) * la.period


def pose_lag(m: mujoco.MjModel) -> float:
    """
    Return how far the data's poses after a step are behind its time: one step, or 0.

    After ``mj_step`` the data's poses (``geom_xpos``, ``xipos``, ...) are those its forward
    pass computed for the state the step started from, one timestep earlier, with Euler and
    the implicit integrators. Runge-Kutta's passes leave those of its last stage: 0, and the
    poses are brought up to date with ``mj_kinematics`` instead.
    """
    if m.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
        return 0.0
    return float(m.opt.timestep)


def request(entities, rate_hz: float = 50.0) -> ContactRequest:
    """
    Ask for the contacts of `entities`, `rate_hz` times per simulated second.

    From the next step on, each is a :class:`~..devices.contacts.ContactReport` named as its
    entity, taken with :meth:`~sim_node.core.world.World.take_sensor_samples`; a name no
    entity has yet is reported once one spawns. The rate is also that of contact sensors
    that declare none.

    :raises InvalidArgumentError: a rate not in (0, :data:`MAX_CONTACT_RATE_HZ`] Hz.
    """
    if isinstance(rate_hz, bool) or not isinstance(rate_hz, (int, float)) \
            or not 0 < rate_hz <= MAX_CONTACT_RATE_HZ:
        raise InvalidArgumentError(
            f'contact rate {rate_hz!r} Hz is not in (0, {MAX_CONTACT_RATE_HZ:g}]')
    return ContactRequest(tuple(dict.fromkeys(str(e) for e in entities)), float(rate_hz))


def joint_requests(requests: tuple, key: str, joints, rate_hz: float,
                   sensors: bool = False, tick: Optional[Callable] = None) -> tuple:
    """
    Return `requests` with `key`'s joints sampled at `rate_hz` (0: not at all any more).

    With `sensors`, each sample carries MuJoCo's sensor values too. A `tick` takes every
    sample due on the stepping thread, with the world lock held, and returns joint commands
    ((names, values, mode) each) that the next step applies (:class:`Sampler`); it must not
    block nor call the world.

    Each sample is a :class:`JointSample` named `key`, taken with
    :meth:`~sim_node.core.world.World.take_sensor_samples`; joints the model lacks (an entity
    deleted) make the request wait for a model that has them all.

    :raises InvalidArgumentError: a rate not in [0, :data:`MAX_JOINT_RATE_HZ`] Hz.
    """
    if isinstance(rate_hz, bool) or not isinstance(rate_hz, (int, float)) \
            or not 0 <= rate_hz <= MAX_JOINT_RATE_HZ:
        raise InvalidArgumentError(
            f'joint sampling rate {rate_hz!r} Hz is not in [0, {MAX_JOINT_RATE_HZ:g}]')
    kept = tuple(r for r in requests if r[0] != key)
    return kept + ((key, tuple(joints), float(rate_hz), bool(sensors), tick),) \
        if rate_hz > 0 else kept


def laser_requests(rates) -> tuple:
    """
    Return the request for lasers' poses, checked.

    :param rates: a site's name -> its scans per simulated second (a site the model lacks
        waits for a model that has it).

    :raises InvalidArgumentError: a rate not in (0, :data:`MAX_LASER_RATE_HZ`] Hz.
    """
    out = []
    for name, rate in dict(rates).items():
        if isinstance(rate, bool) or not isinstance(rate, (int, float)) \
                or not 0 < rate <= MAX_LASER_RATE_HZ:
            raise InvalidArgumentError(
                f'laser {name!r}: rate {rate!r} Hz is not in (0, {MAX_LASER_RATE_HZ:g}]')
        out.append((str(name), float(rate)))
    return tuple(out)


def new_laser_queue() -> deque:
    """Return the queue of :class:`LaserPose` a world's samplers fill and its node drains."""
    return deque(maxlen=LASER_POSES_KEPT)


def new_queue() -> deque:
    """Return the queue a world's samplers fill and its node drains."""
    return deque(maxlen=SAMPLES_KEPT)


def drain(samples: deque) -> list:
    """
    Take every sample queued so far, oldest first; thread-safe, without the world lock.

    Each is (site, simulated time, orientation wxyz, angular velocity, linear acceleration)
    of an IMU a robot file declares, at its own rate (a part the sensor lacks is None), a
    contact sensor's :class:`~..devices.contacts.ContactReport`, a :class:`JointSample`, a
    P3D plugin's :class:`~.odometers.OdometerSample`, or a :class:`~.geo.GeoSample`.
    """
    out = []
    while True:
        try:
            out.append(samples.popleft())
        except IndexError:
            return out
