"""How reachwise compiles its numba kernels: one strategy for ``kinematics``, ``control``
and ``distance``.

1. **Entry points carry explicit signatures.** A kernel that Python calls is declared
   with its signature and ``cache=True``: it is compiled when its module is imported, or
   loaded from numba's on-disk cache, never inside a control loop or a query. A call
   with other argument types raises ``TypeError`` instead of silently compiling a new
   specialization mid-run. There is no warm-up with dummy data anywhere.
2. **Helpers compile into their callers.** A function only kernels call is
   ``@njit(cache=True)`` without a signature; it is compiled with (and cached in) each
   entry point that uses it.
3. **Read-only inputs.** Input arrays are declared read-only and C-contiguous (the types
   below): a writable array converts implicitly and the robot's read-only arrays are
   taken as they are. Outputs and state that a kernel updates are declared writable.
4. **Groups travel as plain tuples.** Inputs that belong together are a ``NamedTuple``
   (a *group*: ``Chain``, ``JointLimits``, …), built and validated once where its data
   is made. An entry point takes a group as the plain tuple of its fields
   (``tuple(group)``, in the field order of its class) and names it again inside
   (``Chain(*chain)``): numba types a plain tuple in C, a named tuple in Python
   (≈ 1 µs per group per call, a few percent of a control tick each).
"""

from __future__ import annotations

from numba import types

__all__ = ["RO_B1_1D", "RO_F8_1D", "RO_F8_2D", "RO_F8_3D", "RO_I8_1D", "W_F8_1D", "W_F8_2D"]


def _ro(dtype: types.Type, ndim: int) -> types.Array:
    return types.Array(dtype, ndim, "C", readonly=True)


#: Read-only C-contiguous input arrays.
RO_F8_1D = _ro(types.float64, 1)
RO_F8_2D = _ro(types.float64, 2)
RO_F8_3D = _ro(types.float64, 3)
RO_I8_1D = _ro(types.int64, 1)
RO_B1_1D = _ro(types.boolean, 1)
#: Writable C-contiguous arrays (outputs, state a kernel updates).
W_F8_1D = types.Array(types.float64, 1, "C")
W_F8_2D = types.Array(types.float64, 2, "C")
