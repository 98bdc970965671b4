"""The descriptive subset of a task (P-II §2, thesis §6.3.1)."""

from __future__ import annotations

import numpy as np
import pytest

from reachwise import load_task
from reachwise.errors import TaskError
from reachwise.tasks.select import descriptive_subset, reach_extremes, task_features
from reachwise.tasks.task import Task


@pytest.fixture(scope="module")
def tunnel() -> Task:
    return load_task("tunnel-87")


def test_subset_bounds_the_required_reach(tunnel: Task) -> None:
    idx = descriptive_subset(tunnel, 16)
    assert len(idx) == 16 and len(set(idx.tolist())) == 16
    assert np.all(np.diff(idx) > 0)
    P, A = tunnel.positions, tunnel.axes
    sub = tunnel.subset(idx)
    # the bounding box of the positions and the range of every axis component are kept
    assert np.allclose(sub.positions.min(0), P.min(0))
    assert np.allclose(sub.positions.max(0), P.max(0))
    assert np.allclose(sub.axes.min(0), A.min(0))
    assert np.allclose(sub.axes.max(0), A.max(0))
    assert set(reach_extremes(tunnel).tolist()) <= set(idx.tolist())


def test_subset_is_deterministic_and_nested_sizes_grow(tunnel: Task) -> None:
    a = descriptive_subset(tunnel, 20)
    b = descriptive_subset(tunnel, 20)
    assert np.array_equal(a, b)
    for n in (1, 3, 12, 30, 86):
        assert len(descriptive_subset(tunnel, n)) == n
    assert np.array_equal(descriptive_subset(tunnel, 87), np.arange(87))
    assert np.array_equal(descriptive_subset(tunnel, 500), np.arange(87))


def test_representatives_cover_the_task(tunnel: Task) -> None:
    """Typical points: every task point is closer to the subset than the task's spread."""
    F = task_features(tunnel)
    for size in (16, 30):
        idx = descriptive_subset(tunnel, size)
        d = np.linalg.norm(F[:, None, :] - F[None, idx, :], axis=2).min(axis=1)
        spread = np.linalg.norm(F - F.mean(0), axis=1).mean()
        assert d.max() < spread
    # representatives improve on extremes alone
    only = descriptive_subset(tunnel, 30, extremes=False)
    assert len(only) == 30


def test_positions_only_task(rng: np.random.Generator) -> None:
    P = rng.uniform(-1, 1, (40, 3))
    t = Task.from_arrays("p3", P, dims=3)
    idx = descriptive_subset(t, 10)
    assert len(idx) == 10
    assert len(reach_extremes(t)) <= 6
    assert np.allclose(P[idx].min(0), P.min(0)) and np.allclose(P[idx].max(0), P.max(0))


def test_bad_size(tunnel: Task) -> None:
    for bad in (0, -3, 2.5, True):
        with pytest.raises(TaskError, match="size"):
            descriptive_subset(tunnel, bad)  # type: ignore[arg-type]
