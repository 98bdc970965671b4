"""How reachwise compiles its numba kernels: one strategy for ``kinematics``, ``control``
and ``distance``.

1. **Entry points carry explicit signatures.** A kernel that Python calls is declared
   with its signature and ``cache=True``: it is compiled when its module is imported, or
   loaded from numba's on-disk cache, never inside a control loop or a query. A call
   with other argument types raises ``TypeError`` instead of silently compiling a new
   specialization mid-run. There is no warm-up with dummy data anywhere.
2. **Helpers compile into their callers.** A function only kernels call is
   ``@njit(cache=True)`` without a signature; it is compiled with (and cached in) each
   entry point that uses it. numba keys that cache on the entry point's own file: after
   changing a helper that lives in another file, delete the cached kernels
   (``find src -name '*.nb[ic]' -delete``) or they keep the old helper.
3. **Read-only inputs.** Input arrays are declared read-only and C-contiguous (the types
   below): a writable array converts implicitly and the robot's read-only arrays are
   taken as they are. Outputs and state that a kernel updates are declared writable.
4. **Groups travel as plain tuples.** Inputs that belong together are a ``NamedTuple``
   (a *group*: ``Chain``, ``JointLimits``, …) with a field specification (:class:`Field`:
   dtype and shape, dimensions by name) from which both its numba type
   (:func:`group_type`) and its validation (:func:`check_group`, an ``InputError``
   naming the group and the field) are derived. A group is built and validated once
   where its data is made. An entry point takes a group as the plain tuple of its
   fields (``tuple(group)``, in the field order of its class) and names it again inside
   (``Chain(*chain)``): numba types a plain tuple in C, a named tuple in Python
   (≈ 1 µs per group per call, a few percent of a control tick each).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import types
from numba.np.numpy_support import from_dtype as numba_from_dtype

from reachwise.errors import InputError

__all__ = [
    "RO_B1_1D",
    "RO_F8_1D",
    "RO_F8_2D",
    "RO_F8_3D",
    "RO_I8_1D",
    "W_F8_1D",
    "W_F8_2D",
    "W_F8_3D",
    "Field",
    "check_group",
    "group_type",
]


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
W_F8_3D = types.Array(types.float64, 3, "C")


# --------------------------------------------------------------------------- groups


@dataclass(frozen=True)
class Field:
    """What one field of a group must be.

    An array (``shape`` given, each entry a length or a dimension's name such as ``"n"``)
    of ``dtype`` (``np.float64``, ``np.int64``, ``np.bool_``), C-contiguous, read-only to
    the kernel unless ``writable``; or a scalar (``shape`` None) of ``dtype`` ``float``,
    ``int`` or ``bool``.
    """

    dtype: type
    shape: tuple[int | str, ...] | None = None
    writable: bool = False

    @property
    def numba_type(self) -> types.Type:
        if self.shape is None:
            return {float: types.float64, int: types.int64, bool: types.boolean}[self.dtype]
        dt = numba_from_dtype(np.dtype(self.dtype))
        return types.Array(dt, len(self.shape), "C", readonly=not self.writable)


def group_type(cls: type, spec: Mapping[str, Field]) -> types.Tuple:
    """The numba type of a group passed as a plain tuple (rule 4), in ``cls``'s field
    order; ``spec`` must describe exactly the fields of the named tuple ``cls``."""
    names = tuple(getattr(cls, "_fields", ()))
    if names != tuple(spec):
        raise TypeError(f"{cls.__name__}: spec fields {tuple(spec)} != {names}")
    return types.Tuple(tuple(spec[f].numba_type for f in names))


def check_group(group: tuple[Any, ...], spec: Mapping[str, Field], dims: dict[str, int]) -> None:
    """Raise :class:`InputError` (source: the group's class, field, reason) unless every
    field of ``group`` matches ``spec``. Named dimensions bind on first use and must
    agree after that, across all the groups checked with the same ``dims``."""
    source = type(group).__name__
    if not isinstance(group, tuple) or tuple(getattr(group, "_fields", ())) != tuple(spec):
        raise InputError(source, "", f"expected the fields {', '.join(spec)}")
    for (name, f), value in zip(spec.items(), group, strict=True):
        if f.shape is None:
            ok = (
                isinstance(value, bool | np.bool_)
                if f.dtype is bool
                else (isinstance(value, f.dtype) and not isinstance(value, bool | np.bool_))
            )
            if not ok:
                raise InputError(source, name, f"expected a {f.dtype.__name__}, got {value!r}")
            continue
        if not isinstance(value, np.ndarray):
            raise InputError(source, name, f"expected an array, got {type(value).__name__}")
        want = np.dtype(f.dtype)
        if value.dtype != want:
            raise InputError(source, name, f"expected dtype {want}, got {value.dtype}")
        if value.ndim != len(f.shape):
            raise InputError(source, name, f"expected {len(f.shape)} dimensions, got {value.shape}")
        for axis, (d, size) in enumerate(zip(f.shape, value.shape, strict=True)):
            expect = dims.setdefault(d, size) if isinstance(d, str) else d
            if size != expect:
                label = f"{d} = {expect}" if isinstance(d, str) else str(expect)
                raise InputError(
                    source, name, f"expected shape {_shape(f.shape)}, got {value.shape}: "
                    f"axis {axis} must be {label}"
                )  # fmt: skip
        if not value.flags.c_contiguous:
            raise InputError(source, name, "must be C-contiguous")
        if f.writable and not value.flags.writeable:
            raise InputError(source, name, "must be writable (the kernel updates it)")


def _shape(shape: tuple[int | str, ...]) -> str:
    return "(" + ", ".join(str(d) for d in shape) + ("," if len(shape) == 1 else "") + ")"
