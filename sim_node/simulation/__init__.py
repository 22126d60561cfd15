"""
A small stepping API for scripts and notebooks: no ROS, no thread.

    from sim_node.simulation import Simulation
    sim = Simulation.from_file('scenes/default.xml')
    sim.step({'left_elbow': -0.5}, dt=0.5, mode='position')
    state = sim.get_state()            # body poses, joint positions (and velocities)
    sim.set_state(state)               # overwrite a scene mid-run, no rebuild
    sim.run(max_steps=10_000)          # with termination constraints

Rules worth knowing:

* A body without mass is static: :meth:`add_object` with ``mass=0`` welds it to the world;
  :meth:`set_mass` with a positive mass frees it (it falls), ``0`` welds it again.
* A body added under another without a joint is welded to it and moves as part of it.
* ``step(dt=...)`` runs a whole number of timesteps: `dt` is rounded to the nearest one
  (halves round up), so the returned time is where the world really is.
* ``run(max_time=T)`` stops after the first step whose time is >= T.
* An object's own friction or restitution wins over surfaces without their own; two objects
  that both have one get MuJoCo's mix (see ``World.set_restitution``).
"""

import math
import time
from typing import Callable, Optional, Sequence, Union

import numpy as np

from ..core.base.config import WorldConfig
from ..core.base.errors import InvalidArgumentError
from ..core.base.records import RESET_STATE, RESET_TIME
from ..core.loop import time_reached
from ..core.models import sources
from ..core.world import World

#: With a window in real time, a long step is shown in slices of this much simulated time.
FRAME_SEC = 1.0 / 60.0
MODES = ('none', 'position', 'velocity', 'effort', 'kinematic')
EMPTY_WORLD = ('<mujoco model="empty"><compiler angle="radian"/><option timestep="0.002"/>'
               '<worldbody><light pos="0 0 4" dir="0 0 -1" directional="true"/>'
               '<geom name="floor" type="plane" size="10 10 0.1" rgba="0.35 0.4 0.45 1"/>'
               '</worldbody></mujoco>')


class Simulation:
    """A :class:`~sim_node.core.world.World` driven step by step from the calling thread."""

    def __init__(self, world: World):
        self.world = world
        self.window = None  # MuJoCo's viewer on this world, once view() opened it
        self._viewed = None  # the Session that holds this world for the window
        self._paced: Optional[tuple] = None  # (wall, simulated) time when pacing began

    @classmethod
    def from_file(cls, path: str, **config) -> 'Simulation':
        return cls(World.from_file(path, WorldConfig(**config)))

    @classmethod
    def from_string(cls, xml: str, **config) -> 'Simulation':
        return cls(World.from_string(xml, WorldConfig(**config)))

    @classmethod
    def empty(cls, **config) -> 'Simulation':
        """Return a world with only a floor, to build in code."""
        return cls.from_string(EMPTY_WORLD, **config)

    # ------------------------------------------------------------------ building

    def add_object(self, name: str, shape: str, size: Sequence[float],
                   position: Sequence[float] = (0, 0, 0),
                   quat_wxyz: Sequence[float] = (1, 0, 0, 0), mass: float = 0.0,
                   rgba: Sequence[float] = (0.7, 0.7, 0.7, 1), friction: Optional[float] = None,
                   restitution: Optional[float] = None) -> str:
        """
        Add a top-level object (box, sphere, cylinder, capsule).

        ``mass=0``: static.
        """
        src = sources.primitive(shape, size, mass=mass, rgba=rgba)
        self.world.spawn(name, src, position, quat_wxyz)
        if friction is not None:
            self.world.set_friction(name, friction)
        if restitution is not None:
            self.world.set_restitution(name, restitution)
        return name

    def add_body(self, name: str, parent: str, shape: str, size: Sequence[float],
                 position: Sequence[float] = (0, 0, 0),
                 quat_wxyz: Sequence[float] = (1, 0, 0, 0), mass: float = 0.0,
                 joint: Optional[str] = None, axis: Sequence[float] = (0, 0, 1),
                 rgba: Sequence[float] = (0.7, 0.7, 0.7, 1)) -> str:
        """Add a body under `parent` (its frame); ``joint=None`` welds it to the parent."""
        return self.world.add_body(name, parent, shape, size, position, quat_wxyz, mass,
                                   joint, axis, rgba)

    def add_model(self, name: str, xml: str, position: Sequence[float] = (0, 0, 0),
                  quat_wxyz: Sequence[float] = (1, 0, 0, 0)) -> str:
        """Add an MJCF or URDF model (text) as one entity."""
        return self.world.spawn(name, sources.from_model_text(xml), position, quat_wxyz)

    def remove(self, name: str) -> None:
        self.world.delete(name)

    # ------------------------------------------------------------------ physics parameters

    def set_mass(self, name: str, mass: float) -> None:
        self.world.set_mass(name, mass)

    def set_friction(self, name: str, sliding: float, torsional: Optional[float] = None,
                     rolling: Optional[float] = None) -> None:
        self.world.set_friction(name, sliding, torsional, rolling)

    def set_restitution(self, name: str, restitution: float) -> None:
        self.world.set_restitution(name, restitution)

    def set_defaults(self, friction: Optional[Sequence[float]] = None,
                     restitution: Optional[float] = None,
                     gravity: Optional[Sequence[float]] = None,
                     timestep: Optional[float] = None) -> None:
        """Global physics defaults; friction/restitution apply to every geom without its own."""
        if friction is not None or restitution is not None:
            self.world.set_default_contact(friction, restitution)
        if gravity is not None:
            self.world.set_gravity(gravity)
        if timestep is not None:
            self.world.set_timestep(timestep)

    # ------------------------------------------------------------------ stepping

    @property
    def time(self) -> float:
        return self.world.time

    @property
    def joint_names(self) -> list:
        return self.world.joint_names()

    def step(self, ctrl: Union[None, dict, Sequence[float]] = None, dt: Optional[float] = None,
             mode: str = 'none') -> float:
        """
        Advance by `dt` seconds (one timestep by default) under a control.

        :param ctrl: {joint: value}, or values for :attr:`joint_names` in order.
        :param dt: rounded to the nearest whole number of timesteps (halves up); at least
            half a timestep.
        :param mode: 'none' (ctrl ignored), 'position', 'velocity', 'effort', or 'kinematic':
            no physics at all, time advances, the commanded joints take the commanded
            positions exactly at every step (velocity: the change over the step) and nothing
            else moves (see ``World.step_kinematic``).
        :returns: the simulation time.
        """
        if mode not in MODES:
            raise InvalidArgumentError(f'unknown mode {mode!r}; use one of {MODES}')
        n = 1 if dt is None else self.steps_for(dt)
        commands = self._as_dict(ctrl)
        if mode != 'none' and mode != 'kinematic' and commands:
            self.world.command(list(commands), list(commands.values()), mode)
        # Watched in real time (view()): in slices of a display frame, each paced.
        chunk = n if self._paced is None else max(1, round(FRAME_SEC / self.world.timestep))
        while n > 0:
            k = min(n, chunk)
            if mode == 'kinematic':
                self.world.step_kinematic(commands, k)
            else:
                self.world.step(k)
            n -= k
            self._pace()
        return self.world.time

    def view(self, real_time: bool = True, **options):
        """
        Open MuJoCo's viewer on this simulation and return the window.

        What the lab's ``C.view`` did. With `real_time`, :meth:`step` waits so that simulated
        time runs no faster than the clock while the window is open, so a person sees the
        motion; closing the window ends the wait. Options go to
        :class:`~sim_node.view.window.Window`.
        """
        from ..session import Session  # above the core: a window attaches from here
        from ..view.window import Window
        if self._viewed is not None:
            self._viewed.close()
        self._viewed = Session(trim_memory=False)
        self._viewed.hold(self.world)
        self.window = Window(self._viewed, **options)
        self._paced = (time.monotonic(), self.world.time) if real_time else None
        return self.window

    @property
    def paced(self) -> bool:
        """Whether :meth:`step` waits for the clock (a window opened by :meth:`view` is open)."""
        return self._paced is not None

    def _pace(self) -> None:
        if self._paced is None:
            return
        if not self.window.is_open:
            self._paced = None
            self._viewed.close()
            return
        wall, sim = self._paced
        now = time.monotonic()
        ahead = (self.world.time - sim) - (now - wall)
        if ahead > 0:
            time.sleep(ahead)
        elif ahead < -FRAME_SEC:  # the script was busy between steps: no burst to catch up
            self._paced = (now, self.world.time)

    def steps_for(self, dt: float) -> int:
        """Return the number of timesteps ``step(dt=dt)`` runs: the nearest, halves rounded up."""
        timestep = self.world.timestep
        if not (math.isfinite(dt) and dt >= 0.5 * timestep):
            raise InvalidArgumentError(f'dt must be at least half a timestep '
                                       f'({timestep} s), got {dt}')
        return int(math.floor(dt / timestep + 0.5))

    def _as_dict(self, ctrl) -> dict:
        if ctrl is None:
            return {}
        if isinstance(ctrl, dict):
            return {str(k): float(v) for k, v in ctrl.items()}
        values = list(np.asarray(ctrl, dtype=float).reshape(-1))
        names = self.world.joint_names()
        if len(values) != len(names):
            raise InvalidArgumentError(f'ctrl has {len(values)} values for {len(names)} joints '
                                       f'{names}')
        return dict(zip(names, values))

    def run(self, max_steps: Optional[int] = None, max_time: Optional[float] = None,
            ctrl: Union[None, dict, Sequence[float]] = None, mode: str = 'none',
            callback: Optional[Callable[['Simulation'], bool]] = None) -> str:
        """
        Step until a termination constraint holds; returns why it stopped.

        :param max_time: stop after the first step whose time is >= max_time.

        :param callback: called after every step; returning True stops the run.
        """
        if max_steps is None and max_time is None and callback is None:
            raise InvalidArgumentError('give max_steps, max_time or a callback, or it never '
                                       'ends')
        steps = 0
        while True:
            if max_steps is not None and steps >= max_steps:
                return 'max_steps'
            if max_time is not None and time_reached(self.world.time, max_time,
                                                     self.world.timestep):
                return 'max_time'
            self.step(ctrl, mode=mode)
            steps += 1
            if mode != 'kinematic':
                ctrl = None  # the world holds a command until replaced: send it once
            if callback is not None and callback(self):
                return 'callback'

    # ------------------------------------------------------------------ state

    def get_state(self, velocities: bool = True) -> dict:
        """
        {'time', 'bodies': {entity: (position, quat_wxyz)}, 'joints': {joint.

        Position}} plus 'body_velocities' {entity: (linear, angular)} and 'joint_velocities'.
        """
        out = {'time': self.world.time, 'bodies': {}, 'joints': {}}
        for rec in self.world.entities():
            st = self.world.get_entity_state(rec.name)
            out['bodies'][rec.name] = (st.position, st.quat_wxyz)
            if velocities:
                out.setdefault('body_velocities', {})[rec.name] = (st.linear_velocity,
                                                                   st.angular_velocity)
        joints = self.world.get_joint_states()
        out['joints'] = {k: v[0] for k, v in joints.items()}
        if velocities:
            out['joint_velocities'] = {k: v[1] for k, v in joints.items()}
        return out

    def set_state(self, state: dict) -> None:
        """
        Overwrite any part of a :meth:`get_state` dict, without rebuilding.

        Bodies' poses (and velocities), joint positions (and velocities); missing parts are left as
        they are. Everything is checked first: an error changes nothing. A static body given a new
        pose is moved (see :meth:`World.overwrite <sim_node.core.world.World.overwrite>`).
        """
        self.world.overwrite(poses=state.get('bodies'), twists=state.get('body_velocities'),
                             joint_positions=state.get('joints'),
                             joint_velocities=state.get('joint_velocities'))

    def reset(self) -> None:
        """Back to the initial (or `home` keyframe) state at time 0, without rebuilding."""
        self.world.reset(RESET_TIME | RESET_STATE)
