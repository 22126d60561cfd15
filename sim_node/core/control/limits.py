"""
A base controller's command limits, applied once per update period as ros2_controllers do.

A :class:`Limiter` limits one command (a speed, an angle) by its value, its change per second
and its second difference, given the two values it sent before (``limit(v, v0, v1, dt)``).
The readers take the limits from a controller's flattened YAML:

* :func:`signed` (diff_drive_controller's ``linear.x.*`` and ``angular.z.*``): ``max_<x>``
  sets a limit, ``min_<x>`` defaults to minus it; absent or NaN: no limit.
* :func:`traction` and :func:`steering` (tricycle_controller's ``traction.*`` and
  ``steering.*``): limits on sizes,
  the sign kept; ``min_<x>`` defaults to 0, ``max_<x>`` to 1000 when only the minimum is
  given; a negative one is refused, as the controller refuses it at configure. A steering
  ``max_position`` is signed, ``min_position`` defaulting to minus it. Traction slowing
  down uses the ``*_deceleration`` limits.

Jazzy's controllers still honour the deprecated ``<prefix>.has_<x>_limits`` flags (Kilted
removes them in favour of NaN limits): a flag set to false turns that limit off whatever
``max_<x>`` and ``min_<x>`` say. Most published YAMLs carry both (``has_jerk_limits: false``
beside ``max_jerk: 0.0``); read as a limit, a jerk of 0 held the wheels still for good. Absent
or true, the limits given apply. ``has_acceleration_limits`` covers the deceleration limits too.

ROS-free; :mod:`sim_node.ros.control.controllers` and :mod:`sim_node.ros.control.steering` use it.
"""

from dataclasses import dataclass
import math
from typing import Optional

#: What tricycle_controller's limiters take for a maximum left out beside a minimum.
BIG = 1000.0


@dataclass(frozen=True)
class Bound:
    """A range [lo, hi]; `sizes`: it bounds |x| and x keeps its sign."""

    lo: float
    hi: float
    sizes: bool = False

    def clamp(self, x: float, scale: float = 1.0) -> float:
        lo, hi = self.lo * scale, self.hi * scale
        if self.sizes:
            return math.copysign(min(max(abs(x), lo), hi), x)
        return min(max(x, lo), hi)


@dataclass(frozen=True)
class Limiter:
    """Limits on a value, its rate and its second difference (None: not limited)."""

    value: Optional[Bound] = None
    rate: Optional[Bound] = None
    second: Optional[Bound] = None
    slowing: Optional[Bound] = None  # the rate's bound while |v| falls (None: `rate`'s)

    @property
    def limits(self) -> bool:
        return any(b is not None for b in (self.value, self.rate, self.second, self.slowing))

    def limit(self, v: float, v0: float, v1: float, dt: float) -> float:
        """Return `v` limited, after `v0` (the last value sent) and `v1` (the one before)."""
        if dt > 0 and self.second is not None:
            dv0 = v0 - v1
            v = v0 + dv0 + self.second.clamp(v - v0 - dv0, 2.0 * dt * dt)
        if dt > 0 and self.rate is not None:
            rate = self.slowing if self.slowing is not None and abs(v) < abs(v0) else self.rate
            v = v0 + rate.clamp(v - v0, dt)
        if self.value is not None:
            v = self.value.clamp(v)
        return v


def _number(params: dict, key: str) -> float:
    value = params.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return math.nan
    return float(value)


def _off(params: dict, prefix: str, name: str) -> bool:
    """
    Say whether the YAML turns a limit off with its deprecated ``has_<x>_limits: false``.

    :raises ValueError: the flag is there but not a bool (the real controller's parameter
        library refuses it at configure).
    """
    key = f"{prefix}.has_{'acceleration' if name == 'deceleration' else name}_limits"
    flag = params.get(key, True)
    if not isinstance(flag, bool):
        raise ValueError(f'{key} is {flag!r}: it must be true or false')
    return not flag


def _signed(params: dict, prefix: str, name: str) -> Optional[Bound]:
    if _off(params, prefix, name):
        return None
    hi, lo = _number(params, f'{prefix}.max_{name}'), _number(params, f'{prefix}.min_{name}')
    if math.isnan(hi) or math.isinf(hi):
        return None
    lo = -hi if math.isnan(lo) else lo
    if lo > hi:
        raise ValueError(f'{prefix}.min_{name} ({lo:g}) is above {prefix}.max_{name} '
                         f'({hi:g})')
    return Bound(lo, hi)


def _sizes(params: dict, prefix: str, name: str) -> Optional[Bound]:
    if _off(params, prefix, name):
        return None
    hi, lo = _number(params, f'{prefix}.max_{name}'), _number(params, f'{prefix}.min_{name}')
    if math.isnan(hi) and math.isnan(lo):
        return None
    hi, lo = BIG if math.isnan(hi) else hi, 0.0 if math.isnan(lo) else lo
    if lo < 0 or hi < 0:
        raise ValueError(f'{prefix}.min_{name} and max_{name} ({lo:g}, {hi:g}) cannot be '
                         'negative: the limits apply to both directions')
    if lo > hi:
        raise ValueError(f'{prefix}.min_{name} ({lo:g}) is above max_{name} ({hi:g})')
    return Bound(lo, hi, sizes=True)


def signed(params: dict, prefix: str) -> Limiter:
    """diff_drive_controller's limits on one axis (``linear.x``, ``angular.z``)."""
    return Limiter(_signed(params, prefix, 'velocity'), _signed(params, prefix, 'acceleration'),
                   _signed(params, prefix, 'jerk'))


def traction(params: dict) -> Limiter:
    """tricycle_controller's limits on its traction wheel's speed (rad/s)."""
    return Limiter(_sizes(params, 'traction', 'velocity'),
                   _sizes(params, 'traction', 'acceleration'),
                   _sizes(params, 'traction', 'jerk'),
                   _sizes(params, 'traction', 'deceleration'))


def steering(params: dict) -> Limiter:
    """tricycle_controller's limits on its steering angle (rad)."""
    return Limiter(_signed(params, 'steering', 'position'),
                   _sizes(params, 'steering', 'velocity'),
                   _sizes(params, 'steering', 'acceleration'))
