"""What another thread sees of a collision service's scene lock while a test holds the
service inside an expensive step (an index build, a depth frame's fuse)."""

from __future__ import annotations

import threading

from reachwise.server import protocol as P
from reachwise.server.service import SceneService


def from_another_thread(svc: SceneService) -> tuple[bool, P.Reply | None]:
    """Whether another thread finds the scene lock free, and (if so) its answer to a
    query of every watched pair."""
    seen: list[tuple[bool, P.Reply | None]] = []

    def look() -> None:
        free = svc.lock.acquire(blocking=False)
        if not free:
            seen.append((False, None))
            return
        svc.lock.release()
        seen.append((True, svc.handle(P.Query(2.0))))

    t = threading.Thread(target=look)
    t.start()
    t.join()
    return seen[0]
