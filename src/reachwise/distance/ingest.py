"""Cloud ingestion off the querying thread: new clouds are indexed on a worker thread.

A depth camera hands over a 300 000-point cloud 30 times a second while the control
loop queries the scene 1000 times a second. Building the new cloud's index
takes milliseconds; the loop must not wait for it. :class:`CloudIngest` takes each
hand-over (:meth:`CloudIngest.submit`: a reference to the points, no copy, no
validation, no build — microseconds), and one worker thread checks the points, makes
the :class:`~reachwise.geometry.cloud.PointCloud` and builds its
:class:`~reachwise.distance.index.CloudIndex` (the tree kernel releases the GIL, so the
querying thread keeps running meanwhile). The querying thread collects what is ready
with :meth:`CloudIngest.take_ready` at the start of a query and swaps it in there:
between two queries, never during one.

Per object only the newest hand-over matters: a cloud still waiting when a newer one
for the same object arrives is dropped unbuilt (:attr:`CloudIngest.superseded` counts
them), and a finished build that a newer finished build overtakes before the query
thread collects it is dropped too. A hand-over whose points are bad (NaN, wrong shape,
empty) never becomes ready: its error is kept (:meth:`CloudIngest.errors`), the object
keeps its previous cloud — which then ages, and a controller that bounds the age of
its clouds stops on it.

Where the time goes (a 300 000-point frame): the hand-over is a dictionary entry under a
lock; the worker copies and checks the points in one compiled pass that also finds
their bounds and centroid (:func:`~reachwise.distance._build.checked_copy`), and builds
the tree from them (:func:`~reachwise.distance.index.index_of_checked`); both release
the GIL, and the Python between them is a few microseconds, so the querying thread is
never held up for long by this one. The querying thread never blocks on it either:
:meth:`CloudIngest.try_take_ready` gives up at once when the worker
holds the lock (the swap then waits for the next query), and clouds swapped out are
handed back (:meth:`CloudIngest.retire`) so that their memory is freed on the worker,
not in a control tick. With ``voxel`` set, each handed-over cloud is thinned to one
point per voxel first (:func:`~reachwise.distance.voxel.voxel_thin`), and the thinned
cloud is the one swapped in: answers are exact on it.

No clock is read here: time stamps come with each hand-over.
"""

from __future__ import annotations

import dataclasses
import os
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from reachwise.distance._build import checked_copy
from reachwise.distance.index import INDICES, CloudIndex, build_index, index_of_checked
from reachwise.distance.voxel import voxel_thin
from reachwise.errors import CloudError, ReachwiseError
from reachwise.geometry.cloud import PointCloud

__all__ = ["CloudIngest", "Ready", "ready_cloud"]


@dataclass(frozen=True, eq=False)
class Ready:
    """A built cloud waiting to be swapped in: object ``name``, its ``version``, the
    ``cloud``, its ``index`` and the time ``stamp`` (s) of its measurement."""

    name: str
    version: int
    cloud: PointCloud
    index: CloudIndex
    stamp: float


@dataclass(frozen=True, eq=False)
class _Job:
    name: str
    version: int
    points: NDArray[np.float64] | PointCloud
    stamp: float


def ready_cloud(
    name: str,
    version: int,
    points: ArrayLike | PointCloud,
    stamp: float,
    voxel: float | None = None,
) -> Ready:
    """Check ``points``, make the cloud and build its index (any thread; raises
    :class:`~reachwise.errors.CloudError` for bad points). An array is copied and
    checked in one compiled pass that also yields the bounds and centroid the index
    needs; a :class:`PointCloud` (checked already) is indexed as it is, or not at all
    when :data:`~reachwise.distance.index.INDICES` holds its index already (a producer
    that built it while making the points, e.g. over a depth image's pixel order:
    :func:`~reachwise.distance.index.index_of_ordered`). ``voxel`` (m):
    keep one point per voxel of that edge first (:func:`voxel_thin`)."""
    if voxel is not None:
        thinned = voxel_thin(points, voxel, name=name)
        return Ready(name, version, thinned, build_index(thinned.points, version=version), stamp)
    if isinstance(points, PointCloud):
        index = INDICES.peek(points)
        if index is None:
            index = build_index(points.points, version=version)
        elif index.version != version:
            index = dataclasses.replace(index, version=version)
        return Ready(name, version, points, index, stamp)
    arr = _frame_array(points, name)
    copy, bad, bounds, centroid = checked_copy(arr)
    if bad:
        raise CloudError(
            name, "points", f"{bad} of {arr.shape[0]} points are not finite (NaN or inf)"
        )
    cloud = PointCloud.of_checked(copy, name=name)
    index = index_of_checked(copy, bounds, centroid, version=version)
    return Ready(name, version, cloud, index, stamp)


def _frame_array(points: ArrayLike, name: str) -> NDArray[np.floating]:
    """``points`` as a float64 or float32 (N, 3) array, N >= 1 (not copied if it is
    one already); CloudError naming the field otherwise."""
    arr = np.asarray(points)
    if arr.dtype not in (np.float64, np.float32):
        try:
            arr = arr.astype(np.float64)
        except (TypeError, ValueError) as exc:
            raise CloudError(name, "points", f"not numeric: {exc}") from None
    if arr.ndim == 1 and arr.shape[0] == 3:
        arr = arr.reshape(1, 3)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise CloudError(name, "points", f"expected shape (N, 3), got {arr.shape}")
    if arr.shape[0] == 0:
        raise CloudError(name, "points", "the cloud is empty")
    return arr


#: How the worker turns a hand-over into a built cloud (``ready_cloud``'s signature).
Build = Callable[[str, int, "NDArray[np.float64] | PointCloud", float, "float | None"], Ready]


def _lower_priority(nice: int) -> None:
    """Make the calling (worker) thread yield to a control loop: a real-time policy
    inherited from the thread that started it (a loop under ``SCHED_FIFO`` that made
    the first hand-over) is dropped for the normal one — a build under it would hold a
    core for its whole length — and the nice value is raised by ``nice``."""
    try:
        if os.sched_getscheduler(0) in (os.SCHED_FIFO, os.SCHED_RR):
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        if nice:
            tid = threading.get_native_id()
            os.setpriority(os.PRIO_PROCESS, tid, os.getpriority(os.PRIO_PROCESS, tid) + nice)
    except OSError:
        pass  # not allowed here: build at the inherited priority


class CloudIngest:
    """One worker thread that builds handed-over clouds (see the module docstring).

    The thread starts with the first :meth:`submit` and stops at :meth:`close` (it is a
    daemon thread, so a forgotten ``close`` never blocks the interpreter's exit).
    ``voxel`` (m, optional): thin every handed-over cloud to one point per voxel.
    ``build``: what the worker runs per hand-over (:func:`ready_cloud`; a test may wrap
    it to hold a build open). ``nice``: on Linux the worker lowers its own scheduling
    priority by this much when it starts (10 by default; 0 keeps it), and never keeps
    a real-time policy inherited from the thread that started it, so that a
    control loop sharing the cores is not preempted by a build: measured in
    ``reachwise bench realtime``, the loop's p99.9 tick fell from 1–2.5 ms to
    0.6 ms, at the same 30 swaps/s. Set it before the first hand-over.
    """

    def __init__(
        self, *, voxel: float | None = None, build: Build = ready_cloud, nice: int = 10
    ) -> None:
        self._cond = threading.Condition()
        self._jobs: dict[str, _Job] = {}
        self._ready: dict[str, Ready] = {}
        self._errors: dict[str, tuple[int, ReachwiseError]] = {}
        self._done: dict[str, int] = {}  # newest version finished (built or failed)
        self._thread: threading.Thread | None = None
        self._closed = False
        self._retired: list[object] = []
        #: What the worker runs per hand-over (``ready_cloud``; a test may hold it open).
        self.build = build
        self.voxel = voxel
        self.nice = nice
        self.builds = 0
        self.superseded = 0
        #: The object whose cloud the worker is building now (None when idle).
        self.building: str | None = None

    # ------------------------------------------------------------------ producer side
    def submit(
        self, name: str, version: int, points: NDArray[np.float64] | PointCloud, stamp: float
    ) -> None:
        """Hand over version ``version`` of object ``name``'s cloud (the points are read
        on the worker thread: do not change them afterwards). A waiting older hand-over
        of the same object is dropped."""
        with self._cond:
            if self._closed:
                raise ReachwiseError("the scene's cloud ingestion is closed")
            if name in self._jobs:
                self.superseded += 1
            self._jobs[name] = _Job(name, version, points, stamp)
            if self._thread is None:
                self._thread = threading.Thread(
                    target=self._run, name="reachwise-cloud-ingest", daemon=True
                )
                self._thread.start()
            self._cond.notify_all()

    def wait(self, name: str, version: int, timeout: float | None = None) -> bool:
        """Block until version ``version`` of ``name`` (or a newer one) has been built or
        has failed; False if ``timeout`` (s) passed first."""
        with self._cond:
            return self._cond.wait_for(
                lambda: self._done.get(name, -1) >= version or self._closed, timeout
            )

    # ------------------------------------------------------------------ consumer side
    @property
    def has_ready(self) -> bool:
        """Whether a built cloud waits to be taken (a plain read, no lock)."""
        return bool(self._ready)

    def take_ready(self) -> list[Ready]:
        """The clouds built since the last call (the newest per object), in no order."""
        if not self._ready:  # a plain read: a build finishing now is taken next time
            return []
        with self._cond:
            out = list(self._ready.values())
            self._ready.clear()
        return out

    def try_take_ready(self) -> list[Ready] | None:
        """:meth:`take_ready` that never waits: None when the worker holds the lock at
        this instant (take them next time)."""
        if not self._ready:
            return []
        if not self._cond.acquire(blocking=False):
            return None
        try:
            out = list(self._ready.values())
            self._ready.clear()
        finally:
            self._cond.release()
        return out

    def retire(self, *objects: object) -> None:
        """Hand back what a swap replaced (an old cloud and its index): the worker drops
        the references, so large arrays are freed on its thread, not the caller's."""
        self._retired.append(objects)  # list.append is atomic: no lock
        if self._thread is None:  # no worker (only blocking swaps): drop them here
            self._retired.clear()

    def errors(self) -> dict[str, tuple[int, ReachwiseError]]:
        """Per object, the newest hand-over that failed: its version and error."""
        with self._cond:
            return dict(self._errors)

    @property
    def running(self) -> bool:
        """Whether the worker thread is alive."""
        return self._thread is not None and self._thread.is_alive()

    @property
    def pending(self) -> int:
        """Hand-overs waiting to be built."""
        return len(self._jobs)

    def stop(self) -> None:
        """Tell the worker to stop without waiting for it: waiting hand-overs are
        dropped, the one in progress ends on the worker (:meth:`close` waits for it)."""
        with self._cond:
            self._closed = True
            self._jobs.clear()
            self._cond.notify_all()

    def close(self) -> None:
        """Stop the worker (waiting hand-overs are dropped; the one in progress ends)."""
        self.stop()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join()
        self._retired.clear()

    # ------------------------------------------------------------------ worker
    def _run(self) -> None:
        if sys.platform == "linux":  # per thread there (a tid is a pid)
            _lower_priority(self.nice)
        while True:
            self._retired.clear()  # free swapped-out clouds here, on the worker
            with self._cond:
                self._cond.wait_for(lambda: bool(self._jobs) or self._closed, timeout=0.1)
                if self._closed:
                    return
                if not self._jobs:
                    continue
                name = next(iter(self._jobs))
                job = self._jobs.pop(name)
                self.building = name
            try:
                ready = self.build(job.name, job.version, job.points, job.stamp, self.voxel)
            except ReachwiseError as exc:
                with self._cond:
                    self.building = None
                    self._errors[job.name] = (job.version, exc)
                    self._done[job.name] = max(self._done.get(job.name, -1), job.version)
                    self._cond.notify_all()
                continue
            del job  # the hand-over's points: freed here, not by whoever drops the next
            with self._cond:
                self.building = None
                self.builds += 1
                old = self._ready.get(name)
                if old is None or old.version < ready.version:
                    self._ready[name] = ready
                self._done[name] = max(self._done.get(name, -1), ready.version)
                self._cond.notify_all()
