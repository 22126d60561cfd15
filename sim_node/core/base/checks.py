"""
Input checks shared by the core: names, finite values, poses.

Error texts are constants so tests can match them.
"""

import difflib
import re
from typing import Optional, Sequence

import numpy as np

from .errors import InvalidArgumentError, InvalidPoseError, NameInvalidError, NamespaceInvalidError

NAME_RE = re.compile(r'^[A-Za-z_][A-Za-z0-9_\-]{0,127}$')
NAMESPACE_RE = re.compile(r'^/?([A-Za-z_][A-Za-z0-9_]*)(/[A-Za-z_][A-Za-z0-9_]*)*$')
# Above this MuJoCo treats a value as divergent (mjMAXVAL); refuse it as input.
MAX_ABS_VALUE = 1e10

ERR_NAME = ("invalid name {name!r}: use letters, digits, '_' or '-', starting with a letter "
            "or '_', at most 128 characters")
ERR_EXTENT = ('position {pos} is outside the world: every coordinate must lie within '
              '{extent:g} m of the origin (the world_extent parameter)')
ERR_NAMESPACE = 'invalid namespace {ns!r}: use a ROS namespace such as /robot1'
ERR_NOT_FINITE = '{what} must be finite numbers, got {value}'
ERR_TOO_LARGE_VALUE = '{what} must be smaller than {limit:g} in magnitude, got {value}'
ERR_COUNT = '{what} needs {n} values, got {got}'
ERR_QUAT = 'orientation must be a unit quaternion (norm {norm:.6f}); normalize it'


def check_finite(what: str, values: Sequence[float], n: Optional[int] = None) -> np.ndarray:
    """
    Values as a float array, refusing NaN, inf and magnitudes MuJoCo calls divergent.

    :param n: the number of values required, if fixed.
    """
    arr = np.asarray(values, dtype=float).reshape(-1)
    if n is not None and arr.size != n:
        raise InvalidArgumentError(ERR_COUNT.format(what=what, n=n, got=arr.size))
    peak = float(np.abs(arr).max()) if arr.size else 0.0  # NaN if any is NaN
    if not peak <= MAX_ABS_VALUE:  # one test on the way every value takes: it is called often
        if not np.all(np.isfinite(arr)):
            raise InvalidArgumentError(ERR_NOT_FINITE.format(what=what, value=arr.tolist()))
        raise InvalidArgumentError(ERR_TOO_LARGE_VALUE.format(what=what, limit=MAX_ABS_VALUE,
                                                              value=arr.tolist()))
    return arr


def check_quat(quat_wxyz: Sequence[float], tol: float = 1e-3) -> np.ndarray:
    """Return a (4,) w,x,y,z quaternion, finite and of unit norm within `tol`, normalized."""
    q = check_finite('orientation', quat_wxyz, 4)
    norm = float(np.linalg.norm(q))
    if abs(norm - 1.0) > tol:
        raise InvalidPoseError(ERR_QUAT.format(norm=norm))
    return q / norm


def check_pose(position: Sequence[float], quat_wxyz: Sequence[float]) -> tuple:
    """(position (3,), quat_wxyz (4,)) checked; any fault is an :class:`InvalidPoseError`."""
    try:
        return check_finite('position', position, 3), check_quat(quat_wxyz)
    except InvalidArgumentError as exc:
        raise InvalidPoseError(str(exc)) from None


def check_extent(position: np.ndarray, extent: float) -> np.ndarray:
    """Refuse (:class:`InvalidPoseError`) a world position outside the cube of half side extent."""
    if float(np.max(np.abs(position))) > extent:
        raise InvalidPoseError(ERR_EXTENT.format(pos=[float(v) for v in position], extent=extent))
    return position


def check_name(name: str) -> str:
    if not NAME_RE.match(name or ''):
        shown = name if len(name or '') <= 100 else f'{name[:100]}... ({len(name)} characters)'
        raise NameInvalidError(ERR_NAME.format(name=shown))
    return name


def check_namespace(namespace: str) -> str:
    if namespace and not NAMESPACE_RE.match(namespace):
        raise NamespaceInvalidError(ERR_NAMESPACE.format(ns=namespace))
    return namespace


def closest_hint(name: str, candidates: Sequence[str]) -> str:
    """Return "; did you mean ...?" naming the closest valid names ('' when none is close)."""
    tail = name.split('/')[-1]
    close = [c for c in candidates if c.split('/')[-1] == tail]
    close += [c for c in difflib.get_close_matches(name, list(candidates), n=3, cutoff=0.6)
              if c not in close]
    return f'; did you mean {", ".join(repr(c) for c in close[:3])}?' if close else ''
