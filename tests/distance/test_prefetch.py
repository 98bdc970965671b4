"""The compiled kernels' cache hint: it is emitted as LLVM's prefetch, with write intent,
and changes no value, for any index, inside the array or past either end."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from reachwise.distance._prefetch import prefetch_for_write


@njit(cache=False)
def _hint_then_write(values, hinted, written):  # type: ignore[no-untyped-def]
    for n in range(hinted.size):
        prefetch_for_write(values, hinted[n])
    for n in range(written.size):
        values[written[n]] += 1.0


@given(
    size=st.integers(1, 200),
    hinted=st.lists(st.integers(-(10**6), 10**6), max_size=30),
    written=st.lists(st.integers(0, 10**6), max_size=30),
)
@settings(max_examples=60, deadline=None)
def test_a_hint_changes_no_value(size: int, hinted: list[int], written: list[int]) -> None:
    rng = np.random.default_rng(size)
    values = rng.standard_normal(size)
    where = np.array([w % size for w in written], dtype=np.int64)
    expected = values.copy()
    np.add.at(expected, where, 1.0)
    _hint_then_write(values, np.array(hinted, dtype=np.int64), where)
    np.testing.assert_array_equal(values, expected)


def test_the_hint_is_an_llvm_prefetch_for_writing() -> None:
    values = np.zeros(8)
    _hint_then_write(values, np.array([3], dtype=np.int64), np.array([], dtype=np.int64))
    llvm = _hint_then_write.inspect_llvm(_hint_then_write.signatures[0])
    calls = [line for line in llvm.splitlines() if "call void @llvm.prefetch" in line]
    assert calls, "no llvm.prefetch in the compiled kernel"
    # (address, rw = 1: write, locality = 3, cache type = 1: data)
    assert all("i32 1, i32 3, i32 1)" in line for line in calls)
