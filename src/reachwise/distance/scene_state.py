"""What a distance scene holds, and the private steps its methods share.

:class:`SceneState` is the state of :class:`~reachwise.distance.Scene`: its objects,
robots and joint states, the watched pairs, the cloud versions and the worker that
indexes handed-over clouds, and the arrays the compiled query reads
(``reachwise.distance.scene_arrays.SceneArrays``). It swaps a built cloud in, places
a robot's frames by forward kinematics, answers pair by pair for the strategies other
than the default, checks time stamps and looks names up (an unknown one is an
:class:`~reachwise.errors.UnknownName` with the closest name). The public methods that
change and query the state are :class:`~reachwise.distance.Scene`'s.
"""

from __future__ import annotations

import math
import numbers
import weakref
from collections.abc import Callable, Mapping
from types import MappingProxyType

import numpy as np
from numpy.typing import NDArray

import reachwise.distance._kernels as K
from reachwise.distance._common import check_pose
from reachwise.distance.answers import write_row
from reachwise.distance.engine import PairQuery, StrategyName
from reachwise.distance.index import INDICES
from reachwise.distance.ingest import CloudIngest, Ready
from reachwise.distance.pairs import WatchedPair
from reachwise.distance.scene_arrays import SceneArrays
from reachwise.distance.scene_plan import QueryPlan
from reachwise.distance.scene_types import RobotLike, SceneObject
from reachwise.errors import InputError, UnknownName
from reachwise.kinematics.fk import fk_all_into
from reachwise.kinematics.robot import Robot

__all__ = ["SceneState", "positive_length"]


class SceneState:
    """The state of a :class:`~reachwise.distance.Scene` and the private steps its
    methods share: objects, robots, joint states, pairs, cloud versions, the indexing
    worker and the arrays the compiled query reads, with the cloud swap, forward
    kinematics into the frame rows, pair-by-pair answers, stamp checks and lookups."""

    strategy: StrategyName
    clock: Callable[[], float] | None
    _voxel: float | None

    def _empty(self) -> None:
        """The state of a scene without robots, objects or pairs."""
        self._objects: dict[str, SceneObject] = {}
        self._robots: dict[str, RobotLike] = {}
        self._q: dict[str, NDArray[np.float64] | None] = {}
        # time stamps (s) of the joint states and run-time poses; NaN = unknown
        self._q_stamp: dict[str, float] = {}
        self._pose_stamp: dict[str, float] = {}
        self._pairs: dict[tuple[str, str], WatchedPair] = {}
        self._queries: dict[tuple[str, str], PairQuery] = {}  # strategies other than default
        self._sequence = 0
        # cloud versions: the one in use per object, the last one handed over, and the
        # time stamp of the one in use (+inf: does not age); the read-only snapshots
        # the answers carry are replaced, never changed, when a cloud is swapped in
        self._versions: Mapping[str, int] = MappingProxyType({})
        self._cloud_stamps: Mapping[str, float] = MappingProxyType({})
        self._issued: dict[str, int] = {}
        self._ingest = CloudIngest(voxel=self._voxel)
        # a scene dropped without close() still stops its worker thread
        self._stop_ingest = weakref.finalize(self, self._ingest.close)
        # the arrays the compiled query reads, and what a query needs of them
        self._arrays = SceneArrays()
        self._slot: dict[str, int] = {}
        self._frame_row: dict[str, int] = {}
        self._plan: QueryPlan | None = None  # rebuilt when the contents change
        self._fresh: set[tuple[str, str]] = set()  # pairs whose warm start is dropped
        self._swaps = 0
        self._deferred = 0
        self._during_build = 0

    def _install(self, ready: Ready) -> None:
        """Swap in a built cloud (unless a newer version is in use already): the object
        takes the cloud, its slot the index (its pairs fresh warm starts); what it
        replaced goes back to the worker to be freed there."""
        if ready.version <= self._versions.get(ready.name, -1):
            return
        obj = self._objects[ready.name]
        INDICES.put(ready.cloud, ready.index)
        self._objects[ready.name] = SceneObject(ready.name, ready.cloud, obj.source)
        old = self._arrays.set_index(self._slot[ready.name], ready.index)
        self._set_version(ready.name, ready.version, ready.stamp)
        for key in self._queries:
            if ready.name in key:
                self._queries[key] = self._make_query(self._pairs[key])
        if self._plan is not None and self._plan.arguments is not None:
            self._plan = self._plan.with_arguments(self._arrays.arguments())
        self._swaps += 1
        self._ingest.retire(obj.cloud, old)

    def _set_version(self, name: str, version: int, stamp: float) -> None:
        """New read-only snapshots of the versions and cloud stamps (answers already
        given keep theirs)."""
        self._versions = MappingProxyType({**self._versions, name: version})
        self._cloud_stamps = MappingProxyType({**self._cloud_stamps, name: stamp})

    # ------------------------------------------------------------------ helpers
    def _forward_kinematics(self, robot: str) -> None:
        """``robot``'s frames into the scene's frame rows: compiled for a
        :class:`~reachwise.kinematics.robot.Robot`, else its ``fk_all`` checked."""
        r = self._robots[robot]
        q = self._q[robot]
        if q is None:
            raise InputError(
                "scene", f"robot {robot!r}", "has no joint state; call set_joints first"
            )
        n = len(r.link_names)
        row = self._frame_row[robot]
        out = self._arrays.frames[row : row + n]
        if isinstance(r, Robot):
            fk_all_into(r, q, out)
            return
        frames = np.asarray(r.fk_all(q), dtype=np.float64)
        if frames.shape != (n, 4, 4):
            raise InputError(
                f"robot {robot!r}", "fk_all", f"expected shape ({n}, 4, 4), got {frames.shape}"
            )
        for k in range(n):
            P = np.ascontiguousarray(frames[k])
            out[k] = P if K.pose_status(P) == 0 else check_pose(P, f"fk_all of {robot!r}")

    def _query_pairwise(self, plan: QueryPlan, rows: NDArray[np.float64]) -> None:
        """Every pair with its own :class:`PairQuery` (strategies other than default)."""
        poses = self._arrays.place()
        slot = self._slot
        for k, p in enumerate(plan.layout):
            write_row(rows[k], self._queries[(p.a, p.b)](poses[slot[p.a]], poses[slot[p.b]]))

    def _stamp(self, stamp: float | None, source: str) -> float:
        """A checked measurement time stamp (s), the clock's reading, or NaN."""
        if stamp is None:
            return self.clock() if self.clock is not None else math.nan
        if (
            isinstance(stamp, bool)
            or not isinstance(stamp, numbers.Real)
            or not math.isfinite(stamp)
        ):
            raise InputError(source, "stamp", f"must be a finite time in s, got {stamp!r}")
        return float(stamp)

    def _make_query(self, pair: WatchedPair) -> PairQuery:
        return PairQuery(
            self._objects[pair.a].cloud,
            self._objects[pair.b].cloud,
            margin=pair.margin,
            strategy=self.strategy,
        )

    def _robot(self, name: str) -> RobotLike:
        r = self._robots.get(name)
        if r is None:
            raise UnknownName("scene", "robot", name, self._robots)
        return r

    def _object(self, name: str) -> SceneObject:
        o = self._objects.get(name)
        if o is None:
            raise UnknownName("scene", "object", name, self._objects)
        return o


def positive_length(value: object, field_name: str) -> float:
    """``value`` as a finite length > 0 (m); else an :class:`~reachwise.errors.InputError`
    naming ``field_name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError("scene", field_name, f"expected a number in metres, got {value!r}")
    v = float(value)
    if not (math.isfinite(v) and v > 0.0):
        raise InputError("scene", field_name, f"must be a finite length > 0 m, got {v!r}")
    return v
