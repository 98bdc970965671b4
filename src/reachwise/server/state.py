"""Durable state of the collision server: the scene survives a crash or a restart.

The collision server of P-IV/P-V keeps the result of the *initialization phase* of P-V
Table 1 — the robots, the part and environment clouds, the pair rules and margins — and
the latest inputs of the *calculation phase* (joint states, run-time poses). Losing it
on a crash would leave the control system without distances until someone registered
everything again, so it is written to a state directory and read back at start:

```
STATE/
  scene.json      robots (YAML mappings), objects (cloud file, pose source), pairs
  clouds/*.npy    one float64 or float32 (N, 3) array per object cloud (np.save, no
                  pickle): the newest saved one of each object
  live.json       last joint states and run-time poses, with their time stamps
  sequence.json   the highest sequence number the server may have handed out
```

Every file is written atomically: to a temporary file in the same folder, flushed and
fsync'ed, then renamed over the old one with :func:`os.replace` (and the folder fsync'ed),
so a reader sees either the old or the new file, never half of one. A cloud is written
under a fresh name before the manifest that refers to it; files no manifest refers to
(left by a crash between the two) are removed at the next load.

``live.json`` is written at most every few hundred milliseconds (the server batches it):
after a crash the restored joint states may be that much older, and their time stamps
say so (the controller's age check sees it). The same holds for streamed clouds
(``replace_cloud``): the newest one of each object is saved at most once a second,
with its version and the stamp of its measurement.

Every file is validated on load; a bad one is a :class:`StateError` naming the file and
the field, and the server stays not-ready rather than starting with half a scene.
"""

from __future__ import annotations

import json
import math
import os
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, TypeVar

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from reachwise.distance.engine import StrategyName
from reachwise.distance.scene import PairKind
from reachwise.errors import InputError
from reachwise.io.atomic import TEMP_SUFFIX, atomic_open, atomic_write
from reachwise.io.validation import input_error

#: Version of the state files; another version is refused (not guessed at).
STATE_VERSION = 1

MANIFEST = "scene.json"
LIVE = "live.json"
SEQUENCE = "sequence.json"
CLOUDS = "clouds"


class StateError(InputError):
    """A state file is unreadable or invalid: ``source`` the file, ``field``, ``reason``."""


_STRICT = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)
Matrix4 = tuple[
    tuple[float, float, float, float],
    tuple[float, float, float, float],
    tuple[float, float, float, float],
    tuple[float, float, float, float],
]


class RobotState(BaseModel):
    """A registered robot: its YAML mapping (``robot_to_dict``)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    name: str = Field(min_length=1)
    model: dict[str, Any]


class ObjectState(BaseModel):
    """A registered object: cloud file (in ``clouds/``), point count and pose source.
    ``pose`` is the world pose (``fixed``), the link offset (``link``) or the initial
    pose (``runtime``; the latest one is in ``live.json``). ``version`` and ``stamp``
    are those of the saved cloud: 0 and the stamp the object was added with for the
    cloud it was added with, else those of the handed-over cloud (``replace_cloud``);
    a stamp is a time (s), None (does not age) or ``"unknown"`` (its age is unknown)."""

    model_config = _STRICT
    name: str = Field(min_length=1)
    cloud: str = Field(pattern=r"^[0-9a-f]{32}\.npy$")
    points: int = Field(ge=1)
    source: Literal["fixed", "link", "runtime"]
    pose: Matrix4
    robot: str | None = None
    link: str | None = None
    version: int = Field(default=0, ge=0)
    stamp: float | Literal["unknown"] | None = None


class PairState(BaseModel):
    """A watched pair, its margin (m, inf allowed) and kind."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=True)
    a: str = Field(min_length=1)
    b: str = Field(min_length=1)
    margin: float = Field(ge=0.0)
    kind: PairKind

    @field_validator("margin")
    @classmethod
    def _not_nan(cls, v: float) -> float:
        if math.isnan(v):
            raise ValueError("margin must not be NaN")
        return v


class MemoryState(BaseModel):
    """A scene memory (``reachwise.distance.scene_memories.add_memory``): its object's
    name, world box (m) and configuration (``MemoryConfig``). Its map is not saved: it
    restarts unknown, never free."""

    model_config = _STRICT
    name: str = Field(min_length=1)
    lower: tuple[float, float, float]
    upper: tuple[float, float, float]
    voxel: float = Field(gt=0.0)
    shadow_depth: float = Field(ge=0.0)
    memory_s: float = Field(ge=0.0)
    free_hold_s: float = Field(ge=0.0)
    band: float | None = Field(default=None, ge=0.0)


class Manifest(BaseModel):
    """``scene.json``: everything of the initialization phase, in registration order
    (pairs in query order)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    version: Literal[1] = 1
    strategy: StrategyName
    robots: tuple[RobotState, ...] = ()
    objects: tuple[ObjectState, ...] = ()
    memories: tuple[MemoryState, ...] = ()
    pairs: tuple[PairState, ...] = ()


class JointState(BaseModel):
    model_config = _STRICT
    q: tuple[float, ...]
    stamp: float


class PoseState(BaseModel):
    model_config = _STRICT
    pose: Matrix4
    stamp: float


class LiveState(BaseModel):
    """``live.json``: the latest joint states and run-time poses with their stamps."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    version: Literal[1] = 1
    joints: dict[str, JointState] = {}
    poses: dict[str, PoseState] = {}


class SequenceState(BaseModel):
    model_config = _STRICT
    version: Literal[1] = 1
    reserved: int = Field(ge=0)


@dataclass(frozen=True)
class Snapshot:
    """What a load returns: the manifest, the live state and every object's points."""

    manifest: Manifest
    live: LiveState
    clouds: dict[str, NDArray[np.float64]]


def matrix4(a: NDArray[np.float64]) -> Matrix4:
    """A 4x4 array as nested tuples (exact floats) for the JSON files."""
    r = [tuple(float(v) for v in row) for row in np.asarray(a, dtype=np.float64).reshape(4, 4)]
    return (r[0], r[1], r[2], r[3])  # type: ignore[return-value]


def _json_bytes(model: BaseModel) -> bytes:
    # json (not pydantic's serializer) so that an infinite margin stays ``Infinity``
    return json.dumps(model.model_dump(mode="python"), indent=1).encode()


class StateStore:
    """The state directory of one server (created if missing)."""

    def __init__(self, root: str | os.PathLike[str]) -> None:
        self.root = Path(root)
        try:
            (self.root / CLOUDS).mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise StateError(
                str(self.root), "", f"cannot create the state directory: {exc}"
            ) from None

    # ------------------------------------------------------------------ writing
    def write_cloud(self, points: NDArray[Any]) -> str:
        """Save a cloud (float32 kept as float32, anything else as float64) under a
        fresh file name (returned); the manifest refers to it. Written straight to the
        file, without a copy in memory (``np.save`` releases the GIL while it writes)."""
        name = f"{uuid.uuid4().hex}.npy"
        arr = np.asarray(points)
        if arr.dtype != np.float32:
            arr = np.asarray(arr, dtype=np.float64)
        with atomic_open(self.root / CLOUDS / name, "wb") as fh:
            np.save(fh, np.ascontiguousarray(arr), allow_pickle=False)
        return name

    def write_manifest(self, manifest: Manifest) -> None:
        atomic_write(self.root / MANIFEST, _json_bytes(manifest))

    def write_live(self, live: LiveState) -> None:
        atomic_write(self.root / LIVE, _json_bytes(live))

    def write_reserved(self, reserved: int) -> None:
        atomic_write(self.root / SEQUENCE, _json_bytes(SequenceState(reserved=reserved)))

    def remove_unreferenced(self, manifest: Manifest) -> list[str]:
        """Delete cloud files and temporary files the manifest does not refer to."""
        keep = {o.cloud for o in manifest.objects}
        removed = []
        clouds = self.root / CLOUDS
        for folder in (self.root, clouds):
            for p in folder.iterdir():
                stale_cloud = folder == clouds and p.suffix == ".npy" and p.name not in keep
                if p.is_file() and (stale_cloud or p.name.endswith(TEMP_SUFFIX)):
                    p.unlink(missing_ok=True)
                    removed.append(p.name)
        return removed

    # ------------------------------------------------------------------ reading
    def read_reserved(self) -> int:
        """The reserved sequence mark (0 for a new directory)."""
        path = self.root / SEQUENCE
        if not path.exists():
            return 0
        return _read_model(path, SequenceState).reserved

    def read(self) -> Snapshot | None:
        """The saved scene, or None if this directory holds none yet."""
        path = self.root / MANIFEST
        if not path.exists():
            return None
        manifest = _read_model(path, Manifest)
        live_path = self.root / LIVE
        live = _read_model(live_path, LiveState) if live_path.exists() else LiveState()
        clouds = {o.name: self._read_cloud(o) for o in manifest.objects}
        return Snapshot(manifest, live, clouds)

    def _read_cloud(self, obj: ObjectState) -> NDArray[np.float64]:
        path = self.root / CLOUDS / obj.cloud
        try:
            arr = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise StateError(
                str(path), f"object {obj.name!r}", f"unreadable cloud: {exc}"
            ) from None
        if arr.dtype not in (np.float64, np.float32) or arr.shape != (obj.points, 3):
            raise StateError(
                str(path),
                f"object {obj.name!r}",
                f"expected float64 or float32 ({obj.points}, 3), got {arr.dtype} {arr.shape}",
            )
        return np.asarray(arr, dtype=np.float64)


_M = TypeVar("_M", bound=BaseModel)


def _read_model(path: Path, model: type[_M]) -> _M:
    try:
        data = json.loads(path.read_bytes())
    except (OSError, ValueError) as exc:
        raise StateError(str(path), "", f"unreadable: {exc}") from None
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise input_error(exc, str(path), StateError, model=model) from None


__all__ = [
    "STATE_VERSION",
    "JointState",
    "LiveState",
    "Manifest",
    "ObjectState",
    "PairState",
    "PoseState",
    "RobotState",
    "Snapshot",
    "StateError",
    "StateStore",
    "atomic_write",
    "matrix4",
]
