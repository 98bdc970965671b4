"""A scene memory rebuilt in the viewer from the cameras' frames, live and in playback.

A simulation log keeps the robots' joints and the moving objects' poses, not the voxel
map: the map depends on every frame fused since the start. :class:`MemoryReplay` fuses
the frames again, in the order the simulation delivered them (delivery tick, then the
camera's place in the scenario, then the frame number: what
``reachwise.sim.sensors.DepthSensor.step`` does each tick), each rendered from the
state at its capture (the robots' logged joints then). So the map shown at a tick is the
map the controller queried at that tick.

Seeking forward fuses the frames delivered since; seeking back returns to the newest
snapshot taken before the target and fuses forward from there. A snapshot is taken
every ``every`` frames; when more than :data:`MAX_SNAPSHOTS` are kept, every other one is
dropped and the spacing doubles, so a long log keeps a bounded number of copies.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from reachwise.distance.scene_memory import MemorySnapshot
    from reachwise.sim.memory_feed import MemoryFeed
    from reachwise.sim.sensors import DepthSensor, Sight

__all__ = ["MAX_SNAPSHOTS", "MemoryReplay"]

#: Most snapshots one replay keeps (each a copy of the voxel grid's three arrays).
MAX_SNAPSHOTS = 16

JointsAt = Callable[[int], dict[str, NDArray[np.float64]] | None]


class _Snapshot(NamedTuple):
    next: tuple[int, ...]  # per camera: the next frame to fuse
    fused: int
    memory: MemorySnapshot


class MemoryReplay:
    """The map of ``feed`` rebuilt from the frames of its cameras ``sensors`` (see the
    module doc). The feed's memory is cleared first: it is the replay's."""

    def __init__(self, feed: MemoryFeed, sensors: Sequence[DepthSensor], every: int = 30) -> None:
        self.feed = feed
        self.sensors = list(sensors)
        self.every = max(1, int(every))
        self.tick = -1  # every frame delivered at or before this tick is fused
        self.next = [0] * len(self.sensors)
        self.fused = 0
        feed.reset()
        self.snapshots = [self._snapshot()]

    def _snapshot(self) -> _Snapshot:
        return _Snapshot(tuple(self.next), self.fused, self.feed.memory.snapshot())

    def needs(self) -> int:
        """The earliest tick whose joints a later :meth:`advance` may still ask for: the
        capture of the next frame to fuse (a live view keeps the joints from there)."""
        if not self.sensors:
            return 0
        return min(s.capture_tick(k) for s, k in zip(self.sensors, self.next, strict=True))

    def _due(self, tick: int) -> int | None:
        """The camera whose next frame comes next in delivery order, if delivered by
        ``tick``."""
        best: tuple[int, int] | None = None
        for i, (s, k) in enumerate(zip(self.sensors, self.next, strict=True)):
            d = s.delivery_tick(k)
            if d <= tick and (best is None or (d, i) < best):
                best = (d, i)
        return None if best is None else best[1]

    def _seek_back(self, tick: int) -> None:
        """Return to the newest snapshot all of whose frames were delivered by ``tick``."""
        for snap in reversed(self.snapshots):
            if all(
                k == 0 or s.delivery_tick(k - 1) <= tick
                for s, k in zip(self.sensors, snap.next, strict=True)
            ):
                break
        self.feed.memory.restore(snap.memory)
        self.feed.dirty = True
        self.next, self.fused = list(snap.next), snap.fused
        self.snapshots = self.snapshots[: self.snapshots.index(snap) + 1]

    def advance(self, tick: int, q_at: JointsAt, sight: Sight) -> bool:
        """The map as the simulation had it at ``tick``; ``q_at(k)`` gives the robots'
        joints at tick ``k`` (None: not known, the replay waits for them). True when the
        map changed."""
        if tick == self.tick:
            return False
        if tick < self.tick:
            self._seek_back(tick)
        changed = tick < self.tick
        while (i := self._due(tick)) is not None:
            sensor, k = self.sensors[i], self.next[i]
            qs = q_at(sensor.capture_tick(k))
            if qs is None:
                return changed  # not complete: the next call goes on from here
            frame = sensor.render(k, sight, qs)
            self.feed.fuse(sensor.camera, frame, sensor.capture_tick(k) * sensor.dt)
            self.next[i] += 1
            self.fused += 1
            changed = True
            if self.fused % self.every == 0:
                self.snapshots.append(self._snapshot())
                if len(self.snapshots) > MAX_SNAPSHOTS:
                    self.snapshots = self.snapshots[::2]
                    self.every *= 2
        self.tick = tick
        return changed
