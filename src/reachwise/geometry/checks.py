"""Checked numbers for the geometry models: each bad value an
:class:`~reachwise.errors.InputError` naming the source, the field and the reason."""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence

import numpy as np

from reachwise.errors import InputError

__all__ = ["finite_number", "interval"]


def finite_number(
    value: object, source: str, field: str, *, positive: bool = False, nonneg: bool = False
) -> float:
    """``value`` as a finite float (> 0 with ``positive``, >= 0 with ``nonneg``)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(source, field, f"expected a number, got {value!r}")
    out = float(value)
    if not math.isfinite(out):
        raise InputError(source, field, f"must be finite, got {out!r}")
    if positive and out <= 0.0:
        raise InputError(source, field, f"must be > 0, got {out!r}")
    if nonneg and out < 0.0:
        raise InputError(source, field, f"must be >= 0, got {out!r}")
    return out


def interval(value: object, source: str, field: str) -> tuple[float, float]:
    """``value`` as a finite ``(min, max)`` pair with ``min <= max``."""
    if not isinstance(value, Sequence | np.ndarray) or len(value) != 2:
        raise InputError(source, field, f"expected (min, max), got {value!r}")
    out = (finite_number(value[0], source, field), finite_number(value[1], source, field))
    if out[0] > out[1]:
        raise InputError(source, field, f"min {out[0]!r} exceeds max {out[1]!r}")
    return out
