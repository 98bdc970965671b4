"""The collision server's state directory: what is persisted, and restoring it.

With a state directory (:class:`reachwise.server.state.StateStore`) every change of
the initialization phase (robots, objects, pair rules) is written as a manifest before
it is acknowledged, the latest joint states and run-time poses every
:data:`LIVE_INTERVAL` seconds, and at start the directory is restored into a fresh
scene before the server becomes ready (a bad state leaves it ``failed``). A scene
memory's setup and watched pairs are kept, not its map: it restarts unknown.
"""

from __future__ import annotations

import logging
import math
from typing import Literal

import numpy as np
from numpy.typing import NDArray

import reachwise.server.protocol as P
from reachwise.distance._common import check_pose
from reachwise.distance.scene import Fixed, OnLink, Scene, SceneObject
from reachwise.distance.scene_memories import add_memory, memory_setups
from reachwise.distance.scene_memory import MemoryConfig
from reachwise.io.robot_file import robot_from_dict
from reachwise.server.service_core import (
    ObjectMeta,
    ObjectSource,
    ServiceCore,
    indexed_cloud,
    stamp_source,
    wire_error,
)
from reachwise.server.state import (
    JointState,
    LiveState,
    Manifest,
    MemoryState,
    ObjectState,
    PairState,
    PoseState,
    RobotState,
    StateStore,
    matrix4,
)

log = logging.getLogger("reachwise.server")

#: How often the writer thread saves the latest joint states and poses (s).
LIVE_INTERVAL = 0.2


class ScenePersistence(ServiceCore):
    """Writing and restoring the state directory of
    :class:`reachwise.server.service.SceneService`."""

    # ------------------------------------------------------------------ persistence
    def _manifest(self) -> Manifest | None:
        """The initialization-phase state to persist (call under the lock); None
        without a state directory."""
        if self.store is None:
            return None
        objects = []
        kept = set()
        for name, obj in self.scene.objects.items():
            meta = self._meta[name]
            if meta.cloud_file is None:  # added by a scene operation: not saved
                continue
            kept.add(name)
            source, pose, robot, link = self._source(name, obj)
            objects.append(
                ObjectState(
                    name=name,
                    cloud=str(meta.cloud_file),
                    points=meta.points,
                    source=source,
                    pose=matrix4(pose),
                    robot=robot,
                    link=link,
                    version=meta.version,
                    stamp=_saved_stamp(meta.stamp),
                )
            )
        memories = tuple(
            MemoryState(
                name=m.name,
                lower=(float(m.lower[0]), float(m.lower[1]), float(m.lower[2])),
                upper=(float(m.upper[0]), float(m.upper[1]), float(m.upper[2])),
                voxel=m.config.voxel,
                shadow_depth=m.config.shadow_depth,
                memory_s=m.config.memory_s,
                free_hold_s=m.config.free_hold_s,
                band=m.config.band,
            )
            for m in memory_setups(self.scene)
        )
        kept.update(m.name for m in memories)  # their setup is kept, their map is not
        return Manifest(
            strategy=self.strategy,
            robots=tuple(RobotState(name=k, model=v) for k, v in self._models.items()),
            objects=tuple(objects),
            memories=memories,
            pairs=tuple(
                PairState(a=p.a, b=p.b, margin=p.margin, kind=p.kind)
                for p in self.scene.pairs
                if p.a in kept and p.b in kept
            ),
        )

    def _source(self, name: str, obj: SceneObject) -> ObjectSource:
        """Where object ``name``'s pose comes from: ``fixed`` (its world pose), ``link``
        (its offset, robot and link) or ``runtime`` (its current pose)."""
        src = obj.source
        if isinstance(src, Fixed):
            return "fixed", src.pose, None, None
        if isinstance(src, OnLink):
            return "link", src.offset, src.robot, src.link
        return "runtime", self._runtime[name][0], None, None

    def _persist(self, manifest: Manifest | None) -> None:
        """Write the manifest; the change is applied already, so a failure is reported
        as such (and in health) rather than as if nothing had happened."""
        if self.store is None or manifest is None:
            return
        try:
            self.store.write_manifest(manifest)
        except OSError as exc:
            self.reason = f"state directory not writable: {exc}"
            log.error("%s", self.reason)
            raise wire_error(
                P.ErrorCode.INTERNAL,
                "state",
                f"applied, but the state directory could not be written: {exc}",
            ) from None
        self.reason = ""

    def _drop_file(self, cloud_file: str | None) -> None:
        if self.store is not None and cloud_file is not None:
            (self.store.root / "clouds" / cloud_file).unlink(missing_ok=True)

    def flush_live(self, force: bool = False) -> None:
        """Save the latest joint states and run-time poses if they changed."""
        if self.store is None or not self.ready or not (self._live_dirty or force):
            return
        with self.lock:
            live = LiveState(
                joints={
                    k: JointState(q=tuple(float(v) for v in q), stamp=t)
                    for k, (q, t) in self._joints.items()
                },
                poses={
                    k: PoseState(pose=matrix4(p), stamp=t) for k, (p, t) in self._runtime.items()
                },
            )
            self._live_dirty = False
        self.store.write_live(live)

    def load(self) -> None:
        """Restore the state directory into a fresh scene, then become ready. A bad
        state leaves the server ``failed`` (not ready) with the reason."""
        if self.store is None:
            self.state = "ready"
            return
        try:
            self._restore(self.store)
        except Exception as exc:
            log.exception("restoring %s failed", self.store.root)
            self.reason = f"restoring {self.store.root} failed: {exc}"
            self.state = "failed"
            return
        self.state = "ready"
        log.info("state restored from %s", self.store.root)

    def _restore(self, store: StateStore) -> None:
        snap = store.read()
        if snap is None:
            return
        m, live = snap.manifest, snap.live
        where = str(store.root / "scene.json")
        scene = Scene(strategy=m.strategy)
        joints: dict[str, tuple[NDArray[np.float64], float]] = {}
        runtime: dict[str, tuple[NDArray[np.float64], float]] = {}
        meta: dict[str, ObjectMeta] = {}
        base: dict[str, int] = {}
        for rs in m.robots:
            robot = robot_from_dict(rs.model, f"{where}: robot {rs.name!r}")
            scene.add_robot(robot)
            js = live.joints.get(robot.name)
            if js is not None:
                q = np.array(js.q, dtype=np.float64)
                scene.set_joints(robot.name, q)
                joints[robot.name] = (q, js.stamp)
        for o in m.objects:
            cloud = indexed_cloud(snap.clouds[o.name], o.name, o.link or "world")
            pose = np.array(o.pose, dtype=np.float64)
            if o.source == "runtime":
                ps = live.poses.get(o.name)
                stamp = self.clock()
                if ps is not None:
                    pose, stamp = np.array(ps.pose, dtype=np.float64), ps.stamp
                runtime[o.name] = (check_pose(pose, o.name), stamp)
            dynamic = o.source == "runtime"
            stamp_kept = _restored_stamp(o)
            timed = o.version > 0 and math.isfinite(stamp_kept)
            obj = scene.add_object(
                o.name, cloud, pose, robot=o.robot, link=o.link, dynamic=dynamic,
                stamp=math.inf if timed else stamp_kept,
            )  # fmt: skip
            source = stamp_source(o.name, obj.source)
            meta[o.name] = ObjectMeta(
                o.cloud, source, o.points, o.version, None if stamp_kept == math.inf else stamp_kept
            )
            if timed:  # a handed-over cloud: its version and stamp go on, as a hand-over's
                swapped = scene.replace_cloud(o.name, cloud, block=True, stamp=stamp_kept)
                base[o.name] = o.version - swapped
            elif o.version > 0:  # the same without a time: its stamp is unknown, as added
                base[o.name] = o.version
        for ms in m.memories:  # the setup of each scene memory; its map starts unknown
            config = MemoryConfig(ms.voxel, ms.shadow_depth, ms.memory_s, ms.free_hold_s, ms.band)
            add_memory(scene, ms.name, np.array(ms.lower), np.array(ms.upper), config)
        for p in m.pairs:
            scene.watch(p.a, p.b, p.margin, kind=p.kind)
        removed = store.remove_unreferenced(m)
        if removed:
            log.info("removed %d unreferenced state files", len(removed))
        with self.lock:
            old_scene, self.scene = self.scene, scene
            self.strategy = m.strategy
            self._models = {rs.name: rs.model for rs in m.robots}
            self._joints = joints
            self._runtime = runtime
            self._meta = meta
            self._version_base = base
            self._unsaved = {}
            self._adopt()  # the robots and the memories' objects
        old_scene.close()


def _restored_stamp(o: ObjectState) -> float:
    """The stamp (s) of a saved cloud as restored: its time; +inf (does not age) for a
    cloud the object was added with and saved without a stamp; NaN (unknown, so stale
    under ``max_cloud_age``) when saved as ``"unknown"``, or for a handed-over cloud
    (``version`` > 0) saved without one, as state files written before stamps were kept
    hold them: its time was never recorded, and a scan must not count as never ageing."""
    if o.stamp == "unknown" or (o.stamp is None and o.version > 0):
        return math.nan
    return math.inf if o.stamp is None else float(o.stamp)


def _saved_stamp(stamp: float | None) -> float | Literal["unknown"] | None:
    """A cloud's stamp as the state file keeps it: NaN (unknown) as ``"unknown"``, +inf
    (does not age) as None."""
    if stamp is None or stamp == math.inf:
        return None
    return "unknown" if math.isnan(stamp) else stamp
