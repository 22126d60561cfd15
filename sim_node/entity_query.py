"""
Which entities match a query: name pattern, categories, tags, a region.

ROS-free: the node turns an ``EntityFilters`` message into these plain values
(``msg_adapters.convert``).
"""

from dataclasses import dataclass
import math
import time
from typing import Optional

import numpy as np
import regex

from .core.errors import InvalidArgumentError
from .core.world import World

ERR_REGEX = 'invalid filter regex {pattern!r}: {err}'
ERR_REGEX_TIME = ('the filter regex took longer than {sec:g} s over the entity names; simplify '
                  'it (nested repetition such as (a+)+ can take exponential time)')
#: Longest a name filter may run over all entity names (s). Filters never run under the world
#: lock; this bounds the service thread too.
FILTER_TIMEOUT_SEC = 0.1


@dataclass(frozen=True)
class Region:
    """An axis-aligned box (``lo``, ``hi`` corners) or a sphere (``center``, ``radius``)."""

    kind: str  # 'box' or 'sphere'
    a: np.ndarray  # box: min corner; sphere: centre
    b: np.ndarray  # box: max corner; sphere: (radius, 0, 0)

    def contains(self, p: np.ndarray) -> bool:
        if self.kind == 'box':
            return bool(np.all(self.a <= p) and np.all(p <= self.b))
        return math.dist(p, self.a) <= float(self.b[0])


def query(world: World, pattern: str = '', categories: Optional[set] = None,
          tags: tuple = (), region: Optional[Region] = None) -> list:
    """
    Entity records, in model order.

    Whose name `pattern` (a regular expression, at most :data:`FILTER_TIMEOUT_SEC` of matching in
    all) finds, whose category is in `categories` (None: any), and whose root body origin lies in
    `region` (None: anywhere). Entities carry no tags, so any tag matches nothing.
    """
    recs = world.entities()
    if pattern:
        try:
            rx = regex.compile(pattern)
        except regex.error as exc:
            raise InvalidArgumentError(ERR_REGEX.format(pattern=pattern, err=exc)) from None
        deadline = time.monotonic() + FILTER_TIMEOUT_SEC
        try:
            recs = [r for r in recs
                    if rx.search(r.name, timeout=max(deadline - time.monotonic(), 1e-6))]
        except TimeoutError:
            raise InvalidArgumentError(ERR_REGEX_TIME.format(sec=FILTER_TIMEOUT_SEC)) from None
    if categories is not None:
        recs = [r for r in recs if r.category in categories]
    if tags:
        recs = []
    if region is not None:
        recs = [r for r in recs if region.contains(world.get_entity_state(r.name).position)]
    return recs
