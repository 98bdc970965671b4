"""A watched pair of a distance scene, and one pair's answer.

:class:`WatchedPair` is a rule of :class:`~reachwise.distance.scene.Scene` (which two
objects, with which margin, and why); :class:`PairResult` the answer to it in a
:class:`~reachwise.distance.scene.SceneResult`. Both are also importable from
:mod:`reachwise.distance.scene`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

from reachwise.distance._common import DistanceResult

__all__ = ["PAIR_KINDS", "PairKind", "PairResult", "WatchedPair"]

#: Why a pair is watched: links of one robot (``self``), a robot and its environment,
#: two robots, or a rule given by hand (``custom``).
PairKind = Literal["self", "robot-environment", "robot-robot", "custom"]
PAIR_KINDS: tuple[PairKind, ...] = get_args(PairKind)


@dataclass(frozen=True)
class WatchedPair:
    """A pair of objects to watch: ``kind`` (``PairKind``), ``margin`` in metres."""

    a: str
    b: str
    margin: float
    kind: PairKind


@dataclass(frozen=True)
class PairResult:
    """One watched pair's answer: object names, margin, kind and the distance result
    (``point_a`` on ``a``; ``direction`` from ``b`` to ``a``), and ``versions``, the
    versions of the two objects' clouds it was computed on (0: the cloud the object was
    added with; see :meth:`Scene.replace_cloud`)."""

    a: str
    b: str
    margin: float
    kind: PairKind
    result: DistanceResult
    versions: tuple[int, int] = (0, 0)
