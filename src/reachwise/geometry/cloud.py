"""The point cloud: an immutable (N, 3) float64 array of points with a frame name.

Points are expressed in the cloud's own frame (``frame``): a link cloud in its link
frame, a scan in ``world``. Queries place the cloud with a 4x4 pose. A cloud is
validated once, at construction: no NaN/inf, at least one point, shape (N, 3).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.errors import CloudError


@dataclass(frozen=True, eq=False)
class PointCloud:
    """An immutable set of 3-D points in metres, expressed in frame ``frame``.

    ``cache`` holds derived acceleration structures (spatial indices) keyed by the
    distance strategy that built them; they depend only on the points, so repeated
    queries against the same cloud do not rebuild them.
    """

    points: NDArray[np.float64]
    frame: str = "world"
    name: str = ""
    cache: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        source = self.name or "point cloud"
        try:
            pts = np.array(self.points, dtype=np.float64, copy=True)
        except (TypeError, ValueError) as exc:
            raise CloudError(source, "points", f"not numeric: {exc}") from None
        if pts.ndim == 1 and pts.shape[0] == 3:
            pts = pts.reshape(1, 3)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise CloudError(source, "points", f"expected shape (N, 3), got {pts.shape}")
        if pts.shape[0] == 0:
            raise CloudError(source, "points", "the cloud is empty")
        bad = ~np.isfinite(pts).all(axis=1)
        if bad.any():
            raise CloudError(
                source,
                "points",
                f"{int(bad.sum())} of {pts.shape[0]} points are not finite (NaN or inf)",
            )
        pts.setflags(write=False)
        object.__setattr__(self, "points", pts)

    @classmethod
    def of(cls, data: PointCloud | ArrayLike, name: str = "") -> PointCloud:
        """Return ``data`` if it is a PointCloud, else wrap the (N, 3) array."""
        if isinstance(data, PointCloud):
            return data
        return cls(np.asarray(data), name=name)

    def __len__(self) -> int:
        return int(self.points.shape[0])

    @property
    def bounds(self) -> NDArray[np.float64]:
        """Axis-aligned bounds in the cloud frame, shape (2, 3): min row, max row."""
        return np.stack([self.points.min(axis=0), self.points.max(axis=0)])

    def transformed(self, pose: ArrayLike, frame: str | None = None) -> PointCloud:
        """The cloud's points mapped by the 4x4 ``pose`` into ``frame``."""
        T = np.asarray(pose, dtype=np.float64)
        pts = self.points @ T[:3, :3].T + T[:3, 3]
        return PointCloud(pts, frame=frame or self.frame, name=self.name)
