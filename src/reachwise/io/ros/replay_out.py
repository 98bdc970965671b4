"""The files of a replay: ``distances.csv``, ``near.csv``, ``summary.json`` and the
results as a bag beside the recording.

- ``distances.csv``: one row per frame and pair with a cloud: ``time`` (s), ``pair``
  (``link|topic``), ``distance`` (m), ``cloud_stamp`` (s, the stamp of the cloud the
  answer used);
- ``near.csv``: the same columns, only the rows closer than the margin;
- ``summary.json``: the inputs, and per pair the smallest distance, when, on which
  cloud, and how many frames came closer than the margin (and the first time);
- the results bag (:func:`write_results_bag`, ROS 2 sqlite3 or MCAP, or ROS 1): per frame
  ``/reachwise/distances`` (``std_msgs/Float64MultiArray``, one value per pair, NaN
  before the pair's first cloud, the pairs in the dimension label separated by
  ``;``), ``/reachwise/min_distance`` (``std_msgs/Float64``) and
  ``/reachwise/closest_points`` (``visualization_msgs/MarkerArray``: a line between the
  closest points of each pair, red when closer than the margin); once, at the first
  frame, ``/reachwise/pairs`` (``std_msgs/String``, the pair names as JSON).
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from reachwise.io.atomic import atomic_open, atomic_write
from reachwise.io.ros.bag_writer import BagWriter
from reachwise.io.ros.replay import ReplayResult

__all__ = ["replay_summary", "write_csv", "write_results_bag", "write_summary"]

_COLUMNS = ("time", "pair", "distance", "cloud_stamp")


def write_csv(result: ReplayResult, path: str | Path, *, near_only: bool = False) -> Path:
    """Every frame's distance of every pair with a cloud (``near_only``: only those
    closer than the margin) as CSV (see the module docstring)."""
    keep = result.near if near_only else ~np.isnan(result.distance)
    with atomic_open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(_COLUMNS)
        for f, p in zip(*np.nonzero(keep), strict=True):
            w.writerow(
                (
                    repr(float(result.t[f])),
                    result.pairs[p],
                    repr(float(result.distance[f, p])),
                    repr(float(result.cloud_stamp[f, p])),
                )
            )
    return Path(path)


def _opt(v: float) -> float | None:
    return None if not math.isfinite(v) else float(v)


def replay_summary(result: ReplayResult, inputs: dict[str, Any]) -> dict[str, Any]:
    """The summary of a replay: ``inputs`` (what was replayed) and per pair the
    smallest distance, its time and cloud stamp, the frames closer than the margin."""
    pairs = []
    near = result.near
    for p, name in enumerate(result.pairs):
        d = result.distance[:, p]
        ok = ~np.isnan(d)
        entry: dict[str, Any] = {"pair": name, "frames": int(ok.sum())}
        if ok.any():
            f = int(np.nanargmin(d))
            entry.update(
                min_distance=float(d[f]),
                at=float(result.t[f]),
                cloud_stamp=_opt(float(result.cloud_stamp[f, p])),
            )
        hits = np.flatnonzero(near[:, p])
        entry["near_frames"] = int(hits.size)
        entry["first_near"] = float(result.t[hits[0]]) if hits.size else None
        pairs.append(entry)
    md = result.min_distance
    finite = ~np.isnan(md)
    return {
        "bag": result.bag,
        "robot": result.robot,
        "frame": result.frame,
        "margin": result.margin,
        "inputs": inputs,
        "frames": int(result.t.size),
        "start": _opt(float(result.t[0])) if result.t.size else None,
        "end": _opt(float(result.t[-1])) if result.t.size else None,
        "clouds_handed_over": result.clouds,
        "clouds_used": result.swapped,
        "min_distance": float(md[finite].min()) if finite.any() else None,
        "near_frames": int(np.any(near, axis=1).sum()),
        "pairs": pairs,
    }


def write_summary(summary: dict[str, Any], path: str | Path) -> Path:
    """``summary.json``."""
    return atomic_write(path, json.dumps(summary, indent=2) + "\n")


def write_results_bag(result: ReplayResult, path: str | Path) -> Path:
    """The results as a bag (``.bag``: ROS 1, ``.mcap``: MCAP, else ROS 2 sqlite3) to
    show beside the recording (see the module docstring)."""
    near = result.near
    with BagWriter(path) as w:
        f = w.factory
        label = ";".join(result.pairs)
        for k, t in enumerate(result.t):
            t = float(t)
            if k == 0:
                w.write(
                    "/reachwise/pairs", "std_msgs/msg/String", f.string(json.dumps(result.pairs)), t
                )
            w.write(
                "/reachwise/distances",
                "std_msgs/msg/Float64MultiArray",
                f.float64_array(label, result.distance[k]),
                t,
            )
            md = result.min_distance[k]
            w.write("/reachwise/min_distance", "std_msgs/msg/Float64", f.float64(md), t)
            w.write(
                "/reachwise/closest_points",
                "visualization_msgs/msg/MarkerArray",
                f.line_markers(t, result.frame, result.point_a[k], result.point_b[k], near[k]),
                t,
            )
    return Path(path)
