"""The P-V scan scenes: public stand-ins for the scans of P-V's obstacle-detection
experiment (§IV, Fig. 3) and for its occlusion study (Fig. 5), by name.

They are scenario data (the choices of ours each docstring lists, not measurements), so
they live with the scenarios; a scenario's ``scanner: p5-floor-obstacle`` names one.
The scanner model and the processing are :mod:`reachwise.geometry.scanner` and
:mod:`reachwise.geometry.scan_scene`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from reachwise.errors import UnknownName
from reachwise.geometry.checks import finite_number
from reachwise.geometry.cloud import DEFAULT_VOXEL
from reachwise.geometry.scan_scene import ScanScene
from reachwise.geometry.scanner import LaserScanner

__all__ = ["SCENES", "get_scene", "p5_floor_obstacle", "p5_occlusion"]

_SRC = "scanner"


def _floor_and_box(
    obstacle_size: tuple[float, float, float], obstacle_center: tuple[float, float]
) -> tuple[Any, Any, NDArray[np.float64]]:
    """A 16 m square floor at z = 0 and a box of ``obstacle_size`` (x, y, z; m) standing
    on it at ``obstacle_center`` (x, y; m): the two trimesh meshes and the box's
    corners ``[[lo xyz], [hi xyz]]`` (InputError for a bad size or centre)."""
    import trimesh

    sx, sy, sz = (finite_number(v, _SRC, "obstacle_size", positive=True) for v in obstacle_size)
    cx, cy = (finite_number(v, _SRC, "obstacle_center") for v in obstacle_center)
    half = 8.0
    floor = trimesh.Trimesh(
        vertices=[[-half, -half, 0.0], [half, -half, 0.0], [half, half, 0.0], [-half, half, 0.0]],
        faces=[[0, 1, 2], [0, 2, 3]],
        process=False,
    )
    box = trimesh.creation.box(extents=(sx, sy, sz))
    box.apply_translation((cx, cy, sz / 2.0))
    corners = np.array([[cx - sx / 2, cy - sy / 2, 0.0], [cx + sx / 2, cy + sy / 2, sz]])
    return floor, box, corners


def p5_floor_obstacle(
    *,
    scanner: LaserScanner | None = None,
    obstacle_size: tuple[float, float, float] = (0.7, 0.8, 0.55),
    obstacle_center: tuple[float, float] = (2.7, 0.0),
) -> ScanScene:
    """A public stand-in for the P-V experiment's scan: a floor with one box obstacle.

    P-V's scan data is not public; P-V §IV and Fig. 3 give only the rig, the processing
    and the result (about 5500 points after cropping and 3 cm downsampling, denser near
    the scanner, a small unseen area behind the obstacle). This scene reproduces those
    facts with choices of ours, not measurements:

    - World frame: floor plane z = 0 (a 16 m x 16 m square of two triangles), x away
      from the scanner, z up.
    - Obstacle: a rock-sized box, 0.70 m (x) x 0.80 m (y) x 0.55 m (z), standing on
      the floor centred at (2.7, 0) m, i.e. 2.35–3.05 m ahead of the scanner.
    - Scanner: optical centre 2.5 m above the floor over the origin (a stand looking
      down at the work area), tilt axis along y, the P-V resolutions (0.25° beams,
      25 Hz lines, 5°/s, so 0.2° between lines), beams from -42° to +42° azimuth,
      tilt 28°–64° below horizontal: a 7.2 s sweep of 181 lines x 337 beams that
      covers the working area.
    - Working area (crop): x 1.5–4.0 m, y ±1.08 m, z -0.1–1.0 m; 3 cm voxels anchored
      at the crop's min corner, so neither the floor nor the box faces lie on a voxel
      plane.

    The scanner height and the working-area size were tuned so that the noise-free
    scan, cropped and downsampled, gives about 5500 points (5496, about 1150 of them
    on the box), and the shadow behind the box (0.86 m long on the centre line, from
    x = 3.05 m to 3.91 m) lies inside the working area, as in P-V Fig. 3. The
    arguments change the obstacle; ``scanner`` replaces the default scanner.
    """
    floor, box, obstacle = _floor_and_box(obstacle_size, obstacle_center)
    if scanner is None:
        pose = np.eye(4)
        pose[:3, 3] = (0.0, 0.0, 2.5)
        scanner = LaserScanner(
            pose=pose,
            azimuth_range=(math.radians(-42.0), math.radians(42.0)),
            tilt_range=(math.radians(28.0), math.radians(64.0)),
        )
    return ScanScene(
        name="p5-floor-obstacle",
        meshes=(floor, box),
        scanner=scanner,
        crop_min=np.array([1.5, -1.08, -0.1]),
        crop_max=np.array([4.0, 1.08, 1.0]),
        voxel=DEFAULT_VOXEL,
        obstacles=(obstacle,),
        description="P-V stand-in: a floor with a box obstacle, nodding scanner 2.5 m up",
        ground=0.0,
    )


def p5_occlusion(
    *,
    scanner: LaserScanner | None = None,
    obstacle_size: tuple[float, float, float] = (0.7, 0.8, 1.0),
    obstacle_center: tuple[float, float] = (2.7, 0.0),
) -> ScanScene:
    """A variant of :func:`p5_floor_obstacle` whose scan misses the obstacle's far half.

    Our choice, for the occlusion study (P-V Fig. 5: the return path went
    wrong behind the obstacle, where the scan had no points): the same floor and a
    taller box, 0.70 (x) x 0.80 (y) x 1.00 (z) m centred at (2.7, 0) m, scanned by the
    P-V scanner (same resolutions) standing low in front of it, behind the crane,
    optical centre at (-1.0, 0, 0.8) m, below the box's top: every beam that reaches
    the box hits its front face (x = 2.35 m); its top, its sides, its back and the
    floor behind it are in shadow. Beams from -30° to +30° azimuth, tilt from 10°
    above to 30° below the horizon (an 8 s sweep). Working area (crop): x 1.5–4.0 m, y ±1.5 m,
    z -0.1–1.5 m, 3 cm voxels anchored at its min corner. So the cloud is the floor
    around the obstacle and one face of it: whatever passes behind that face sees
    nothing, which :func:`shadow_points` fills.
    """
    floor, box, obstacle = _floor_and_box(obstacle_size, obstacle_center)
    if scanner is None:
        pose = np.eye(4)
        pose[:3, 3] = (-1.0, 0.0, 0.8)
        scanner = LaserScanner(
            pose=pose,
            azimuth_range=(math.radians(-30.0), math.radians(30.0)),
            tilt_range=(math.radians(-10.0), math.radians(30.0)),
        )
    return ScanScene(
        name="p5-occlusion",
        meshes=(floor, box),
        scanner=scanner,
        crop_min=np.array([1.5, -1.5, -0.1]),
        crop_max=np.array([4.0, 1.5, 1.5]),
        voxel=DEFAULT_VOXEL,
        obstacles=(obstacle,),
        description="P-V occlusion variant: a 1 m box seen only from the front, scanner 0.8 m up",
        ground=0.0,
    )


#: Built-in scenes by name.
SCENES: dict[str, Callable[[], ScanScene]] = {
    "p5-floor-obstacle": p5_floor_obstacle,
    "p5-occlusion": p5_occlusion,
}


def get_scene(name: str) -> ScanScene:
    """The built-in scene ``name`` (see :data:`SCENES`)."""
    if name not in SCENES:
        raise UnknownName("scene", "scene", name, SCENES)
    return SCENES[name]()
