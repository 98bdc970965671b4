"""Automatic self-collision pairs for a scenario, computed once and cached.

A scenario's ``watch: [{self: arm, pairs: auto, margin: 0.05}]`` (or ``self: {robot: arm,
pairs: auto}``) watches the pairs :func:`reachwise.distance.self_pairs.
self_collision_pairs` picks for the robot's link clouds in the scene, with the watch's
margin, the robot's ``q0`` as the home configuration and ``samples`` random joint
vectors. The result is kept in memory under a fingerprint of everything it depends on
(the robot's joints, limits, base and tool, the clouds' points, margin, samples, seed,
home), so a baseline run, an avoidance run, a report and a viewer of the same scenario
compute it once; and, when the scenario has a results folder (``Scenario.cache_dir``,
set by ``reachwise simulate --out DIR``), it is written there as
``self-pairs-<robot>.yaml`` (:mod:`reachwise.io.pairs_file`) and read back by later runs
with the same fingerprint. The file's ``key`` seals the fingerprint together with every
field of the pairs (:func:`reachwise.io.pairs_file.seal`): a cached file that fails its
checks, or whose content no longer matches its key (a pair deleted, a margin edited), is
recomputed and rewritten, and the log says so. Every load logs (``reachwise.sim``,
INFO) the pairs excluded as always within the margin, each with its clearance, and
warns of the watched pairs already within it at home.
"""

from __future__ import annotations

import hashlib
import logging
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from reachwise.distance.self_pairs import SelfPairs, self_collision_pairs
from reachwise.errors import InputError
from reachwise.geometry.cloud import PointCloud
from reachwise.io.pairs_file import load_pairs, save_pairs, seal
from reachwise.kinematics.robot import Robot

__all__ = ["auto_self_pairs", "pairs_key"]

_MEMORY: dict[str, SelfPairs] = {}
log = logging.getLogger("reachwise.sim")


def pairs_key(
    robot: Robot,
    clouds: Mapping[str, PointCloud],
    margin: float,
    samples: int,
    seed: int,
    home: np.ndarray,
) -> str:
    """A fingerprint of everything the pairs depend on (hex SHA-256)."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(robot.dh).tobytes())
    h.update(np.ascontiguousarray(robot.lower).tobytes())
    h.update(np.ascontiguousarray(robot.upper).tobytes())
    h.update(np.ascontiguousarray(robot.base).tobytes())
    h.update(np.ascontiguousarray(robot.tool).tobytes())
    h.update(repr([(j.type, j.passive) for j in robot.joints]).encode())
    for link in sorted(clouds):
        h.update(link.encode())
        h.update(np.ascontiguousarray(clouds[link].points).tobytes())
    h.update(repr((float(margin), int(samples), int(seed))).encode())
    h.update(np.ascontiguousarray(home, dtype=float).tobytes())
    return h.hexdigest()


def auto_self_pairs(
    robot: Robot,
    clouds: Mapping[str, PointCloud],
    margin: float,
    *,
    home: np.ndarray,
    samples: int = 10_000,
    seed: int = 0,
    cache_dir: Path | None = None,
    label: str | None = None,
) -> SelfPairs:
    """The self-collision pairs of ``robot`` with ``clouds`` (see the module docstring);
    ``label`` names the cache file (default: the robot's name)."""
    key = pairs_key(robot, clouds, margin, samples, seed, home)
    hit = _MEMORY.get(key)
    file = None if cache_dir is None else Path(cache_dir) / f"self-pairs-{label or robot.name}.yaml"
    stored = _cached(file, key) if file is not None else None
    if hit is None:
        hit = stored
    if hit is None:
        hit = self_collision_pairs(robot, clouds, margin, samples=samples, seed=seed, home=home)
    _MEMORY[key] = hit
    if file is not None and stored is None:
        file.parent.mkdir(parents=True, exist_ok=True)
        save_pairs(hit, file, source=robot.source or "", key=key)
    _report(hit, label or robot.name)
    return hit


def _report(pairs: SelfPairs, label: str) -> None:
    """Log the pairs excluded as always within the margin, those watched with a margin
    of their own, and the watched pairs within their margin at home."""
    for p in pairs.always:
        log.info(
            "%s: self pair %s-%s excluded, always within the %g m margin (%s)",
            label, p.a, p.b, pairs.margin, p.detail,
        )  # fmt: skip
    for p in pairs.pairs:
        if p.margin is not None:
            log.info(
                "%s: self pair %s-%s watched with its own %.4f m margin (%s)",
                label, p.a, p.b, p.margin, p.detail,
            )  # fmt: skip
    for p in pairs.review:
        log.warning(
            "%s: self pair %s-%s is %.4f m apart at home, within its %g m margin",
            label, p.a, p.b, p.home_distance, pairs.margins[(p.a, p.b)],
        )  # fmt: skip


def _cached(file: Path, key: str) -> SelfPairs | None:
    """The pairs in cache ``file`` when it holds pairs sealed with ``key``, else ``None``
    (logged when a file is there but refused)."""
    if not file.is_file():
        return None
    try:
        pairs, stored = load_pairs(file)
    except InputError as exc:
        log.warning("%s: not used, the pairs are computed again (%s)", file, exc)
        return None
    if stored != seal(pairs, key):
        log.warning(
            "%s: does not match its key (the robot, its clouds, the settings or the pairs "
            "changed): the pairs are computed again",
            file,
        )
        return None
    return pairs
