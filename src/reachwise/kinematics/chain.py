"""The serial chain packed as arrays for the compiled kernels: the group ``Chain``
(see ``reachwise.kinematics._jit`` for how groups reach a kernel)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from reachwise.kinematics._jit import Field, group_type

__all__ = ["CHAIN", "CHAIN_SPEC", "Chain"]


class Chain(NamedTuple):
    """``Robot.arrays``: the chain of ``N`` joints (fixed ones included).

    ``kind`` (N,) 0 revolute, 1 prismatic, 2 fixed; ``qidx`` (N,) index into ``q``, -1
    for a fixed joint; ``dh`` (N, 4) the DH rows ``a, alpha, d, theta``; ``classic`` the
    convention (False: modified DH); ``base``, ``tool`` (4, 4) poses.
    """

    kind: NDArray[np.int64]
    qidx: NDArray[np.int64]
    dh: NDArray[np.float64]
    classic: bool
    base: NDArray[np.float64]
    tool: NDArray[np.float64]


CHAIN_SPEC = {
    "kind": Field(np.int64, ("N",)),
    "qidx": Field(np.int64, ("N",)),
    "dh": Field(np.float64, ("N", 4)),
    "classic": Field(bool),
    "base": Field(np.float64, (4, 4)),
    "tool": Field(np.float64, (4, 4)),
}
#: numba type of a ``Chain`` passed to an entry point as a plain tuple.
CHAIN = group_type(Chain, CHAIN_SPEC)
