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

from .base.errors import InvalidArgumentError
from .world import World

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

    def overlaps(self, lo: np.ndarray, hi: np.ndarray) -> bool:
        """Whether the box with corners `lo`, `hi` (an entity's bounds) meets this region."""
        if self.kind == 'box':
            a, b = np.minimum(self.a, self.b), np.maximum(self.a, self.b)  # either corner order
            return bool(np.all(a <= hi) and np.all(lo <= b))
        nearest = np.clip(self.a, lo, hi)  # the point of the box closest to the centre
        return math.dist(nearest, self.a) <= float(self.b[0])


def query(world: World, pattern: str = '', categories: Optional[set] = None,
          tags: tuple = (), region: Optional[Region] = None) -> list:
    """
    Entity records, in model order.

    Whose name `pattern` (a regular expression, at most :data:`FILTER_TIMEOUT_SEC` of matching in
    all) finds, whose category is in `categories` (None: any), and whose axis-aligned bounds in
    the world frame meet `region` (None: anywhere): overlap, as the standard says, not the
    origin inside.
    Entities carry no tags (ENTITY_TAGS is not listed): the node refuses tag filters.
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
        recs = [r for r in recs if region.overlaps(*world.entity_bounds(r.name))]
    return recs
