"""Fixtures shared by the viewer tests."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from reachwise.viz.viewer import Viewer


@pytest.fixture
def viewer() -> Iterator[Viewer]:
    """A viewer on a free port, stopped after the test."""
    v = Viewer(port=0)
    try:
        yield v
    finally:
        v.stop()
