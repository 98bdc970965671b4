"""What the kinematic functions read of a robot: :class:`KinematicModel`, the part of
:class:`reachwise.kinematics.robot.Robot` that forward kinematics, the Jacobians and
the inverse kinematics use. They are typed against it, so ``robot.py`` (whose methods
call them) and they do not import each other in a circle."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.kinematics.chain import Chain

__all__ = ["KinematicModel"]


class KinematicModel(Protocol):
    """A serial chain with names and joint limits (a ``Robot`` is one)."""

    @property
    def name(self) -> str: ...

    @property
    def joints(self) -> Sequence[object]: ...

    @property
    def n(self) -> int:
        """Number of non-fixed joints (the length of ``q``)."""
        ...

    @property
    def link_names(self) -> tuple[str, ...]: ...

    @property
    def lower(self) -> NDArray[np.float64]: ...

    @property
    def upper(self) -> NDArray[np.float64]: ...

    @property
    def prismatic(self) -> NDArray[np.bool_]: ...

    @property
    def arrays(self) -> Chain: ...

    def link_index(self, link: int | str) -> int: ...

    def within_limits(self, q: ArrayLike, tol: float = 0.0) -> NDArray[np.bool_] | bool: ...
