"""A scene to scan and the processing of its scan (P-V §IV): the meshes, the scanner,
the working area kept and the voxel the cloud is thinned to.

:func:`scan_scene` sweeps the scene's scanner once and returns the raw scan and the
cropped, downsampled cloud (with the occlusion fill of
:mod:`reachwise.geometry.occlusion` when asked). The built-in P-V scenes are scenario
data and live with the scenarios (:mod:`reachwise.sim.p5_scenes`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import InputError
from reachwise.geometry.cloud import (
    DEFAULT_VOXEL,
    PointCloud,
    crop,
    crop_mask,
    voxel_downsample,
    voxel_keys,
)
from reachwise.geometry.occlusion import OcclusionFill
from reachwise.geometry.raycast import Engine
from reachwise.geometry.scanner import LaserScanner, Scan

if TYPE_CHECKING:
    import trimesh

__all__ = ["ScanScene", "scan_scene"]


@dataclass(frozen=True, eq=False)
class ScanScene:
    """A scene to scan: meshes (world frame), a scanner, and the post-processing box.

    ``crop_min``/``crop_max`` bound the working area kept (P-V §IV: "points located
    outside the working area were removed"); ``voxel`` is the downsampling voxel edge,
    anchored at ``crop_min``. ``obstacles`` lists the (2, 3) ``[min, max]`` corners of
    each box obstacle, for analysis and tests.
    """

    name: str
    meshes: tuple[trimesh.Trimesh, ...]
    scanner: LaserScanner
    crop_min: NDArray[np.float64]
    crop_max: NDArray[np.float64]
    voxel: float = DEFAULT_VOXEL
    obstacles: tuple[NDArray[np.float64], ...] = ()
    description: str = ""
    ground: float | None = None

    def process(self, cloud: PointCloud, virtual: NDArray[np.float64] | None = None) -> PointCloud:
        """Crop to the working area, then voxel-downsample (P-V §IV).

        ``virtual`` points (an occlusion fill) are cropped and downsampled on the same
        grid, and kept only in voxels that hold no measured point (a measured surface
        is never replaced by a virtual point) and that lie on the boundary of the
        occupied voxels (the inside of a filled shadow adds points but no distance).
        """
        measured = voxel_downsample(
            crop(cloud, self.crop_min, self.crop_max), self.voxel, self.crop_min
        )
        if virtual is None or len(virtual) == 0:
            return measured
        inside = crop_mask(virtual, self.crop_min, self.crop_max)
        if not inside.any():
            return measured
        virt = voxel_downsample(virtual[inside], self.voxel, self.crop_min)
        seen = {tuple(k) for k in voxel_keys(measured, self.voxel, self.crop_min).tolist()}
        keys = [tuple(k) for k in voxel_keys(virt, self.voxel, self.crop_min).tolist()]
        occupied = seen.union(keys)
        # keep the virtual voxels on the boundary of the occupied region: one whose six
        # face neighbours are all occupied is inside it and never the nearest point to
        # anything outside by more than a voxel
        steps = ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))
        keep = np.array(
            [
                k not in seen
                and not all((k[0] + a, k[1] + b, k[2] + c) in occupied for a, b, c in steps)
                for k in keys
            ],
            dtype=bool,
        )
        if not keep.any():
            return measured
        pts = np.concatenate([measured.points, virt.points[keep]])
        return PointCloud(pts, frame=measured.frame, name=measured.name)

    def virtual_points(self, scan: Scan, fill: OcclusionFill) -> NDArray[np.float64]:
        """The occlusion fill of ``scan`` with this scene's voxel and ground as the
        defaults of ``fill``."""
        spacing = self.voxel if fill.spacing is None else fill.spacing
        ground = self.ground if fill.ground is None else fill.ground
        pts, _ = scan.shadow(fill.depth, spacing, ground)
        return pts


def scan_scene(
    scene: ScanScene,
    rng: np.random.Generator | int | None = None,
    *,
    noise: float | None = None,
    coarsen: float = 1.0,
    engine: Engine = "auto",
    occlusion: OcclusionFill | None = None,
) -> tuple[Scan, PointCloud]:
    """Scan ``scene`` once; return the raw scan and the cropped, downsampled cloud.

    ``noise`` overrides the scanner's range noise (m, standard deviation); ``coarsen``
    multiplies its beam and line spacing (see :meth:`LaserScanner.coarsened`);
    ``occlusion`` adds the occlusion fill
    (:func:`~reachwise.geometry.occlusion.shadow_points`) to the processed cloud (the
    raw scan keeps the measured returns only). A built-in scene by name:
    ``scan_scene(reachwise.sim.p5_scenes.get_scene(name))``.
    """
    if not isinstance(scene, ScanScene):
        raise InputError("scanner", "scene", f"expected a ScanScene, got {type(scene).__name__}")
    sc = scene
    scanner = sc.scanner
    if noise is not None:
        scanner = replace(scanner, range_noise=noise)
    if coarsen != 1.0:
        scanner = scanner.coarsened(coarsen)
    raw = scanner.scan(list(sc.meshes), rng, engine=engine, name=sc.name)
    if occlusion is None:
        return raw, sc.process(raw.cloud)
    return raw, sc.process(raw.cloud, sc.virtual_points(raw, occlusion))
