"""
A controller manager's bookkeeping, as ros2_control's controller_manager keeps it: ROS-free.

Controllers go ``unconfigured`` (loaded) -> ``inactive`` (configured) -> ``active`` and back;
each claims the command interfaces its type and parameters name (``<joint>/<interface>``),
which the robot's ``<ros2_control>`` block must declare, and no two active controllers share
one. Every refusal is ``(False, message)`` naming what is wrong, as the real manager answers
``ok: false`` and logs why; nothing is half-applied: a refused switch changes no state.

Switch strictness (controller_manager_msgs/SwitchController): ``STRICT`` refuses the whole
switch if any controller cannot switch; ``BEST_EFFORT`` switches those that can; ``AUTO`` is
``STRICT`` here (no chained controllers, whose order AUTO resolves); ``FORCE_AUTO`` also
deactivates active controllers that hold an interface a controller to activate claims.

:mod:`sim_node.ros.control.controller_manager` serves it on the wire; :mod:`.controller_types` says
what each controller type claims and needs.
"""

from dataclasses import dataclass, field
import threading
from typing import Optional

from . import controller_types

UNCONFIGURED, INACTIVE, ACTIVE = 'unconfigured', 'inactive', 'active'
BEST_EFFORT, STRICT, AUTO, FORCE_AUTO = 1, 2, 3, 4
#: The controller manager's update rate when its YAML gives none (controller_manager's).
DEFAULT_UPDATE_RATE = 100


@dataclass
class Controller:
    """A loaded controller: its name, type, parameters and lifecycle state."""

    name: str
    kind: str
    params: dict = field(default_factory=dict)
    state: str = UNCONFIGURED
    #: Set by configure: the interfaces it claims and needs, its joints, its rate.
    claims: tuple = ()
    joints: tuple = ()
    update_rate: int = DEFAULT_UPDATE_RATE


class Manager:
    """
    The controllers of one robot.

    :param command_interfaces: ``<joint>/<interface>`` -> (min, max) its hardware declares.
    :param state_interfaces: ``<joint or sensor>/<interface>`` it declares.
    :param parameters: the manager's parameters (``update_rate``, ``<controller>.type``,
        ``<controller>.params_file``...) as dotted names; `controller_params(name)` returns a
        controller's own from the YAML files.
    """

    def __init__(self, command_interfaces: dict, state_interfaces: tuple, parameters: dict,
                 controller_params):
        self.command_interfaces = dict(command_interfaces)
        self.state_interfaces = tuple(state_interfaces)
        self.parameters = parameters
        self._controller_params = controller_params
        self.controllers: dict = {}  # name -> Controller, in load order
        self.lock = threading.RLock()

    @property
    def update_rate(self) -> int:
        rate = self.parameters.get('update_rate', DEFAULT_UPDATE_RATE)
        return int(rate) if isinstance(rate, (int, float)) and rate > 0 else DEFAULT_UPDATE_RATE

    def claimed(self) -> dict:
        """Return interface -> the active controller that claims it."""
        return {i: c.name for c in self.controllers.values() if c.state == ACTIVE
                for i in c.claims}

    # ------------------------------------------------------------------ lifecycle

    def load(self, name: str) -> tuple:
        with self.lock:
            if name in self.controllers:
                return False, f"a controller named '{name}' is already loaded"
            kind = self.parameters.get(f'{name}.type')
            if not kind:
                return False, (f"the 'type' parameter of controller '{name}' is not set: give "
                               f"it in the controllers YAML or with the spawner's -t")
            if kind not in controller_types.TYPES:
                return False, (f"controller type '{kind}' of '{name}' is not one this "
                               f"simulator provides ({', '.join(sorted(controller_types.TYPES))})")
            try:
                params = self._controller_params(name)
            except ValueError as exc:
                return False, f"the parameters of controller '{name}': {exc}"
            self.controllers[name] = Controller(name=name, kind=kind, params=params)
            return True, f"loaded '{name}' ({kind})"

    def configure(self, name: str) -> tuple:
        with self.lock:
            c = self.controllers.get(name)
            if c is None:
                return False, f"no controller named '{name}' is loaded"
            if c.state == ACTIVE:
                return False, f"controller '{name}' is active: deactivate it first"
            try:
                params = self._controller_params(name)
                spec = controller_types.configure(c.kind, params, self)
            except ValueError as exc:
                c.state = UNCONFIGURED
                return False, f"controller '{name}' ({c.kind}) cannot be configured: {exc}"
            c.params, c.claims, c.joints = spec.params, spec.claims, spec.joints
            rate = params.get('update_rate', self.update_rate)
            c.update_rate = int(rate) if isinstance(rate, (int, float)) and 0 < rate <= \
                self.update_rate else self.update_rate
            c.state = INACTIVE
            return True, f"configured '{name}'"

    def cleanup(self, name: str) -> tuple:
        with self.lock:
            c = self.controllers.get(name)
            if c is None:
                return False, f"no controller named '{name}' is loaded"
            if c.state != INACTIVE:
                return False, f"controller '{name}' is {c.state}: only an inactive one is " \
                    'cleaned up'
            c.state = UNCONFIGURED
            return True, f"cleaned up '{name}'"

    def unload(self, name: str) -> tuple:
        with self.lock:
            c = self.controllers.get(name)
            if c is None:
                return False, f"no controller named '{name}' is loaded"
            if c.state == ACTIVE:
                return False, f"controller '{name}' is active: deactivate it before unloading"
            del self.controllers[name]
            return True, f"unloaded '{name}'"

    def switch(self, activate, deactivate, strictness: int) -> tuple:
        """
        Return (ok, message, activated, deactivated): the switch, all of it or nothing.

        With ``BEST_EFFORT`` what cannot switch is left out, said in the message.
        """
        with self.lock:
            if strictness not in (BEST_EFFORT, STRICT, AUTO, FORCE_AUTO):
                return False, f'strictness {strictness} is not 1 to 4', [], []
            activate, deactivate = list(dict.fromkeys(activate)), list(dict.fromkeys(deactivate))
            if not activate and not deactivate:
                return True, 'nothing to switch', [], []
            problems, off, on = [], [], []
            for name in deactivate:
                c = self.controllers.get(name)
                why = (f"controller '{name}' is not loaded" if c is None else
                       None if c.state == ACTIVE else f"controller '{name}' is not active")
                (problems.append(why) if why else off.append(name))
            held = {i: n for i, n in self.claimed().items() if n not in off}
            for name in activate:
                c = self.controllers.get(name)
                why = self._why_not(c, name, held, strictness == FORCE_AUTO)
                if why:
                    problems.append(why)
                    continue
                if strictness == FORCE_AUTO:
                    off += [n for i, n in held.items() if i in c.claims and n not in off]
                    held = {i: n for i, n in held.items() if n not in off}
                held.update({i: name for i in c.claims})
                on.append(name)
            if problems and strictness != BEST_EFFORT:
                return False, '; '.join(problems), [], []
            for name in off:
                self.controllers[name].state = INACTIVE
            for name in on:
                self.controllers[name].state = ACTIVE
            note = ('; left out: ' + '; '.join(problems)) if problems else ''
            return True, f'activated {on}, deactivated {off}{note}', on, off

    def _why_not(self, c: Optional[Controller], name: str, held: dict,
                 force: bool) -> Optional[str]:
        if c is None:
            return f"controller '{name}' is not loaded"
        if c.state == ACTIVE:
            return f"controller '{name}' is already active"
        if c.state != INACTIVE:
            return f"controller '{name}' is {c.state}: configure it first"
        missing = [i for i in c.claims if i not in self.command_interfaces]
        if missing:
            return (f"controller '{name}' claims {', '.join(missing)}, which the robot's "
                    '<ros2_control> block does not declare')
        taken = [f'{i} (held by {held[i]})' for i in c.claims if i in held]
        if taken and not force:
            return f"controller '{name}' claims {', '.join(taken)}"
        return None
