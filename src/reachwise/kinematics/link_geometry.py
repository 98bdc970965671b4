"""The collision (and visual) shapes of a robot link, in the link's frame.

A link carries any number of shapes (a URDF link may have several ``<collision>``
elements; the Z1, Kinova and SO-101 arms do): boxes, cylinders and capsules (axis z,
centred), spheres and triangle meshes, each placed in the link frame by its own
``origin``. The link's point cloud samples all of them together, by area (P-III §5:
1000 points per part; :func:`reachwise.io.robot_clouds.link_clouds`).

Every number is checked when a shape is made: sizes, radii and lengths finite and
> 0, a mesh scale of three finite non-zero factors (a negative factor mirrors the mesh),
a rigid origin. :func:`check_shape` raises :class:`~reachwise.errors.InputError` whose
field names the offending parameter; file readers catch it and name the file and the
element.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np

from reachwise.errors import InputError
from reachwise.kinematics.transforms import Pose, check_pose

__all__ = ["SHAPES", "LinkGeometry", "ShapeKind", "check_shape", "shapes_by_link"]

ShapeKind = Literal["mesh", "box", "cylinder", "sphere", "capsule"]
#: Shape kinds a link may carry.
SHAPES: tuple[str, ...] = ("mesh", "box", "cylinder", "sphere", "capsule")
_IDENTITY = ((1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0), (0.0, 0.0, 0.0, 1.0))


@dataclass(frozen=True)
class LinkGeometry:
    """One shape of a link, in the link frame.

    ``shape``: ``box`` (``size``: edge lengths x, y, z), ``cylinder`` (``radius``,
    ``length`` along z, centred), ``capsule`` (a cylinder of ``radius`` and ``length``
    with hemispherical caps: total length ``length + 2 radius``), ``sphere``
    (``radius``) or ``mesh`` (``mesh``: the file or URI as written; ``scale``: factors
    on the mesh's x, y, z; ``path``: the file it was resolved to when the robot was
    loaded). ``points`` is the number of surface samples of the link's cloud (1000 in
    the thesis; a link with several shapes takes the largest ``points`` of its shapes
    and spreads them by area). ``origin`` places the shape in the link frame. ``label``
    says where the shape came from (``link 'panda_link3' <collision> 1``), for messages.
    """

    shape: ShapeKind
    mesh: str | None = None
    size: tuple[float, float, float] | None = None
    radius: float | None = None
    length: float | None = None
    points: int = 1000
    origin: tuple[tuple[float, ...], ...] = _IDENTITY
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    path: str | None = None
    label: str = ""

    def __post_init__(self) -> None:
        check_shape(self)

    @property
    def origin_matrix(self) -> Pose:
        return np.array(self.origin, dtype=float)


def _positive(where: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise InputError("geometry", where, f"expected a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v) or v <= 0.0:
        raise InputError("geometry", where, f"must be finite and > 0, got {v!r}")
    return v


def check_shape(g: LinkGeometry) -> None:
    """Raise :class:`InputError` (field = the bad parameter) unless ``g`` is a valid
    shape: see :class:`LinkGeometry`."""
    if g.shape not in SHAPES:
        raise InputError("geometry", "shape", f"unknown shape {g.shape!r}; use one of {SHAPES}")
    if g.shape == "box":
        if g.size is None or len(g.size) != 3:
            raise InputError("geometry", "size", f"a box needs three sizes, got {g.size!r}")
        for v in g.size:
            _positive("size", v)
    if g.shape in ("cylinder", "capsule", "sphere"):
        if g.radius is None:
            raise InputError("geometry", "radius", f"a {g.shape} needs a radius")
        _positive("radius", g.radius)
    if g.shape in ("cylinder", "capsule"):
        if g.length is None:
            raise InputError("geometry", "length", f"a {g.shape} needs a length")
        _positive("length", g.length)
    if g.shape == "mesh":
        if not isinstance(g.mesh, str) or not g.mesh.strip():
            raise InputError("geometry", "mesh", "a mesh needs a file name")
        if len(g.scale) != 3:
            raise InputError("geometry", "scale", f"needs three factors, got {g.scale!r}")
        for v in g.scale:
            f = float(v)
            if not math.isfinite(f) or f == 0.0:
                raise InputError("geometry", "scale", f"factors must be finite and ≠ 0, got {v!r}")
    if isinstance(g.points, bool) or not isinstance(g.points, int) or g.points <= 0:
        raise InputError("geometry", "points", f"must be an integer > 0, got {g.points!r}")
    O = np.asarray(g.origin, dtype=float)
    if O.shape != (4, 4) or not np.isfinite(O).all():
        raise InputError("geometry", "origin", "must be a finite 4x4 transform")
    check_pose(O, "geometry origin")


def shapes_by_link(
    source: str,
    geometry: Mapping[str, LinkGeometry | Iterable[LinkGeometry]],
    field: str = "geometry",
) -> dict[str, tuple[LinkGeometry, ...]]:
    """``{link: (shape, ...)}`` from a mapping whose values are one shape or several
    (a single :class:`LinkGeometry` is the one-shape tuple). Links without shapes are
    dropped; anything that is not a shape is an :class:`InputError`."""
    out: dict[str, tuple[LinkGeometry, ...]] = {}
    for link, value in geometry.items():
        items = (value,) if isinstance(value, LinkGeometry) else tuple(value)
        for g in items:
            if not isinstance(g, LinkGeometry):
                raise InputError(source, f"{field}.{link}", f"not a LinkGeometry: {g!r}")
        if items:
            out[str(link)] = items
    return out
