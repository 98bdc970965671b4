"""reachwise: design serial robotic manipulators from their task, move them without collisions.

Public API (stable names, see DESIGN.md): ``load_robot``, ``Robot``, ``PointCloud``,
``distance.closest_points``.
"""

from __future__ import annotations

__version__ = "0.1.0"

from reachwise.geometry.cloud import PointCloud  # noqa: E402

__all__ = ["PointCloud", "__version__"]
