"""The answer of :func:`reachwise.distance.self_pairs.self_collision_pairs`: each link
pair's rule (:class:`PairRule`) and the robot's pairs (:class:`SelfPairs`), and what the
computation needs of a robot (:class:`ChainLike`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.kinematics.bodies import Body

__all__ = ["ChainLike", "PairRule", "Rule", "SelfPairs"]

Rule = Literal["adjacent", "always", "never", "watched"]


class ChainLike(Protocol):
    """What the computation needs of a robot (``reachwise.kinematics.Robot`` has it)."""

    @property
    def name(self) -> str: ...

    @property
    def n(self) -> int: ...

    @property
    def link_names(self) -> tuple[str, ...]: ...

    @property
    def movable_joints(self) -> tuple[int, ...]: ...

    @property
    def lower(self) -> NDArray[np.float64]: ...

    @property
    def upper(self) -> NDArray[np.float64]: ...

    @property
    def body_tree(self) -> Mapping[str, Body]: ...

    @property
    def body_names(self) -> tuple[str, ...]: ...

    def link_index(self, link: str) -> int: ...

    def fk_all(self, q: ArrayLike) -> NDArray[np.float64]: ...


@dataclass(frozen=True)
class PairRule:
    """One link pair: ``rule`` is ``adjacent``, ``always`` or ``never`` (excluded) or
    ``watched``;
    ``detail`` says why in words; ``home_distance`` (m) is the exact distance at the
    home configuration (``inf`` for adjacent pairs, which are not measured);
    ``review`` marks a watched pair within the margin at home; ``margin`` (m) is a
    watched pair's own margin between the surfaces when it has one (a structurally
    close pair, :mod:`reachwise.distance.self_pairs`), else ``None`` (the pairs' common margin)."""

    a: str
    b: str
    rule: Rule
    detail: str
    home_distance: float = math.inf
    review: bool = False
    margin: float | None = None


@dataclass(frozen=True, eq=False)
class SelfPairs:
    """The self-collision pairs of ``robot`` (:mod:`reachwise.distance.self_pairs`)."""

    robot: str
    margin: float
    samples: int
    seed: int
    home: NDArray[np.float64]
    pairs: tuple[PairRule, ...]

    @property
    def watched(self) -> tuple[tuple[str, str], ...]:
        return tuple((p.a, p.b) for p in self.pairs if p.rule == "watched")

    @property
    def excluded(self) -> tuple[PairRule, ...]:
        return tuple(p for p in self.pairs if p.rule != "watched")

    @property
    def review(self) -> tuple[PairRule, ...]:
        return tuple(p for p in self.pairs if p.review)

    @property
    def margins(self) -> dict[tuple[str, str], float]:
        """Each watched pair's margin (m, between the surfaces): its own, else
        :attr:`margin`."""
        return {
            (p.a, p.b): self.margin if p.margin is None else p.margin
            for p in self.pairs
            if p.rule == "watched"
        }

    @property
    def always(self) -> tuple[PairRule, ...]:
        """The pairs excluded as always within the margin
        (:mod:`reachwise.distance.self_pairs`)."""
        return tuple(p for p in self.pairs if p.rule == "always")
