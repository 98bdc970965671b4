"""The layout of a scene's answers: what a client and the server agree on so that the
per-tick messages can leave every name out.

A query reply of the full protocol names its watched pairs, the objects of its cloud
table and the robots (:class:`~reachwise.server.protocol.replies.QueryReply`) under a
``layout`` name. A client that holds that layout sends later queries as binary ticks
(:mod:`~reachwise.server.protocol.tick`) that refer to robots and objects by their
index in it, and gets back rows in its pair order: no names, no maps, one frame each
way. The server changes the layout's key whenever a pair, object or robot changes and
at every start; a tick naming another key is refused (``stale_layout``) and the client
falls back to the full protocol, which sends the new lists.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from reachwise.server.protocol.replies import PairInfo, QueryReply

__all__ = ["MAX_LAYOUT_KEY", "Layout", "layout_key"]

#: Layout keys are 1 … 2**64 - 1 (0 stands for "no layout").
MAX_LAYOUT_KEY = 2**64 - 1


def layout_key(name: str) -> int:
    """The key a layout name stands for: the name is its decimal digits; 0 for a name
    that is not a key (the empty name of a query of chosen pairs, a foreign one)."""
    if not (0 < len(name) <= 20 and name.isascii() and name.isdigit()):
        return 0
    key = int(name)
    return key if key <= MAX_LAYOUT_KEY else 0


@dataclass(frozen=True, eq=False)
class Layout:
    """Watched ``pairs`` in answer order, the ``objects`` of the cloud table and the
    ``robots`` a tick's joint entries refer to, under ``key`` (0: a one-off list, e.g.
    of chosen pairs, that no tick can refer to)."""

    key: int
    pairs: tuple[PairInfo, ...]
    objects: tuple[str, ...]
    robots: tuple[str, ...]

    @cached_property
    def name(self) -> str:
        """The layout's name in the full protocol (empty for key 0)."""
        return str(self.key) if self.key else ""

    @cached_property
    def robot_index(self) -> dict[str, int]:
        return {name: i for i, name in enumerate(self.robots)}

    @cached_property
    def object_index(self) -> dict[str, int]:
        return {name: i for i, name in enumerate(self.objects)}

    @cached_property
    def pair_objects(self) -> NDArray[np.intp]:
        """(P, 2): the rows of each pair's objects in the cloud table (-1: not listed)."""
        idx = self.object_index
        out = np.array([(idx.get(p.a, -1), idx.get(p.b, -1)) for p in self.pairs], dtype=np.intp)
        return out.reshape(len(self.pairs), 2)

    @classmethod
    def of(cls, reply: QueryReply) -> Layout | None:
        """The layout a full query reply sends (None when it leaves the lists out)."""
        if reply.pairs is None:
            return None
        return cls(layout_key(reply.layout), reply.pairs, reply.objects or (), reply.robots or ())
