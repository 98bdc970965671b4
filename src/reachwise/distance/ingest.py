"""Cloud ingestion off the querying thread: new clouds are indexed on a worker thread.

A depth camera hands over a 300 000-point cloud 30 times a second while the control
loop queries the scene 1000 times a second (issue 17). Building the new cloud's index
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

No clock is read here: time stamps come with each hand-over.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from reachwise.distance.index import CloudIndex, build_index
from reachwise.errors import ReachwiseError
from reachwise.geometry.cloud import PointCloud

__all__ = ["CloudIngest", "Ready"]


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
    name: str, version: int, points: NDArray[np.float64] | PointCloud, stamp: float
) -> Ready:
    """Check ``points``, make the cloud and build its index (any thread; raises
    :class:`~reachwise.errors.CloudError` for bad points)."""
    cloud = points if isinstance(points, PointCloud) else PointCloud(points, name=name)
    index = build_index(cloud.points, version=version)
    return Ready(name, version, cloud, index, stamp)


class CloudIngest:
    """One worker thread that builds handed-over clouds (see the module docstring).

    The thread starts with the first :meth:`submit` and stops at :meth:`close` (it is a
    daemon thread, so a forgotten ``close`` never blocks the interpreter's exit).
    """

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._jobs: dict[str, _Job] = {}
        self._ready: dict[str, Ready] = {}
        self._errors: dict[str, tuple[int, ReachwiseError]] = {}
        self._done: dict[str, int] = {}  # newest version finished (built or failed)
        self._thread: threading.Thread | None = None
        self._closed = False
        self.builds = 0
        self.superseded = 0

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
    def take_ready(self) -> list[Ready]:
        """The clouds built since the last call (the newest per object), in no order."""
        if not self._ready:  # a plain read: a build finishing now is taken next time
            return []
        with self._cond:
            out = list(self._ready.values())
            self._ready.clear()
        return out

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

    def close(self) -> None:
        """Stop the worker (waiting hand-overs are dropped; the one in progress ends)."""
        with self._cond:
            self._closed = True
            self._jobs.clear()
            self._cond.notify_all()
            thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join()

    # ------------------------------------------------------------------ worker
    def _run(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: bool(self._jobs) or self._closed)
                if self._closed:
                    return
                name = next(iter(self._jobs))
                job = self._jobs.pop(name)
            try:
                ready = ready_cloud(job.name, job.version, job.points, job.stamp)
            except ReachwiseError as exc:
                with self._cond:
                    self._errors[job.name] = (job.version, exc)
                    self._done[job.name] = max(self._done.get(job.name, -1), job.version)
                    self._cond.notify_all()
                continue
            with self._cond:
                self.builds += 1
                old = self._ready.get(job.name)
                if old is None or old.version < job.version:
                    self._ready[job.name] = ready
                self._done[job.name] = max(self._done.get(job.name, -1), job.version)
                self._cond.notify_all()
