"""Pure geometry: point clouds, bounding volumes and the laser-scanner model."""

from reachwise.geometry.cloud import PointCloud

__all__ = ["PointCloud"]
