"""Streamed clouds on the collision server: hand-over, ``block`` replies and lazy saving.

New clouds (``replace_cloud``: a scan, a depth camera's frames at 30 Hz) are handed to
the scene as the in-process scene takes them
(:meth:`reachwise.distance.Scene.replace_cloud` with ``block=False``): the reply, with
the cloud's version, goes out at once; the scene's worker thread indexes the cloud, and
the first query after that swaps it in. With ``block`` the reply waits until that
version is indexed (:class:`~reachwise.server.service_core.CloudWait`). With a state
directory the newest cloud of each object is saved lazily, at most every
:data:`CLOUD_INTERVAL` seconds and once it has been indexed.
"""

from __future__ import annotations

import math
import time

import reachwise.server.protocol as P
from reachwise.server.persistence import ScenePersistence
from reachwise.server.service_core import CloudWait, ObjectMeta, wire_error

#: How often the writer thread saves the newest streamed cloud of each object (s).
CLOUD_INTERVAL = 1.0
#: Longest a ``block`` hand-over waits for its cloud to be indexed (s).
BLOCK_LIMIT = 120.0


class CloudHandover(ScenePersistence):
    """The ``replace_cloud`` handler of :class:`reachwise.server.service.SceneService`
    and the saving of streamed clouds."""

    def _replace_cloud(self, req: P.ReplaceCloud) -> P.Reply:
        """Hand the cloud over and reply with its version; with ``block`` wait here (up
        to :data:`BLOCK_LIMIT`) until it is indexed. The transport does not call this
        for ``block``: it parks the :class:`CloudWait` instead (:meth:`settle`)."""
        wait = self.hand_over(req)
        if not req.block:
            return P.ObjectReply(wait.name, len(wait.points), wait.version)
        wait.ingest.wait(wait.name, wait.scene_version, BLOCK_LIMIT)
        reply = self.settle(wait)
        if reply is None:
            raise wire_error(
                P.ErrorCode.INTERNAL,
                "cloud",
                f"version {wait.version} of {wait.name!r} was not indexed in {BLOCK_LIMIT:g} s",
            )
        return reply

    def hand_over(self, req: P.ReplaceCloud) -> CloudWait:
        """Give the scene the new cloud (no copy, no build here: its worker indexes it)
        and remember it for the state directory; raises for an unknown object."""
        if not self.ready:
            raise wire_error(P.ErrorCode.NOT_READY, "op", f"the server is {self.state}")
        stamp = self.clock() if req.stamp is None else req.stamp
        with self.lock:
            self._object(req.name, "body.name")
            v = self.scene.replace_cloud(req.name, req.cloud, block=False, stamp=stamp)
            wait = CloudWait(
                req.name,
                v + self._version_base.get(req.name, 0),
                v,
                self.scene.ingest,
                self.scene.generation,
                req.cloud,
                stamp,
                time.monotonic() + BLOCK_LIMIT if req.block else math.inf,
            )
            if self.store is not None:
                self._unsaved[req.name] = wait
        return wait

    def settle(self, wait: CloudWait) -> P.ObjectReply | None:
        """The reply to a ``block`` hand-over once its version (or a newer one) is
        indexed, None while it is not; raises ``invalid`` for a cloud whose points were
        refused, ``unknown_id`` when the scene was cleared meanwhile."""
        if not wait.ingest.wait(wait.name, wait.scene_version, 0.0):
            return None
        with self.lock:
            if wait.generation != self.scene.generation:
                raise wire_error(
                    P.ErrorCode.UNKNOWN_ID, "body.name", "the scene was cleared meanwhile"
                )
            failed = wait.ingest.errors().get(wait.name)
            if failed is not None and failed[0] == wait.scene_version:
                raise wire_error(P.ErrorCode.INVALID, "cloud", str(failed[1]))
            self.scene.swap_in()  # in use from now on, not only from the next query
        return P.ObjectReply(wait.name, len(wait.points), wait.version)

    def flush_clouds(self, force: bool = False, timeout: float = 0.0) -> None:
        """Save the newest handed-over cloud of each object (writer thread), at most
        every :data:`CLOUD_INTERVAL` s unless ``force``; only indexed clouds are saved
        (``timeout`` s to wait for builds in progress), never refused ones."""
        if self.store is None or not self._unsaved or not self.ready:
            return
        now = time.monotonic()
        if not force and now - self._clouds_saved_at < CLOUD_INTERVAL:
            return
        self._clouds_saved_at = now
        with self.lock:
            pending = list(self._unsaved.values())
        for w in pending:
            if not w.ingest.wait(w.name, w.scene_version, timeout):
                continue  # still being indexed: the next round
            failed = w.ingest.errors().get(w.name)
            refused = failed is not None and failed[0] == w.scene_version
            cloud_file = None if refused else self.store.write_cloud(w.points)
            with self.lock:
                current = self._unsaved.get(w.name) is w
                if current:
                    del self._unsaved[w.name]
                old = self._meta.get(w.name)
                if cloud_file is None or w.generation != self.scene.generation or old is None:
                    manifest = None
                else:
                    self._meta[w.name] = ObjectMeta(
                        cloud_file, old.stamp_of, len(w.points), w.version, w.stamp
                    )
                    manifest = self._manifest()
            if manifest is None:
                self._drop_file(cloud_file)
                continue
            try:
                self._persist(manifest)
            except P.ProtocolError:
                continue  # reported in health; the next change retries
            if old is not None:
                self._drop_file(old.cloud_file)
