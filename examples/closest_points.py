"""Exact shortest distance between two point clouds, checked against brute force, and a
figure of the pair.

Usage: python examples/closest_points.py [OUT_FOLDER]   (writes closest_points.png there)
"""

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy.spatial.distance import cdist

import reachwise
from reachwise.distance import closest_points

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
rng = np.random.default_rng(0)
part = reachwise.PointCloud(rng.normal(scale=0.3, size=(1000, 3)))
scan = reachwise.PointCloud(rng.normal(scale=0.5, size=(5000, 3)) + np.array([2.5, 0.0, 0.0]))

d = closest_points(part, scan, margin=5.0)
brute = cdist(part.points, scan.points).min()
print(f"distance {d.distance:.6f} m (brute force {brute:.6f} m)")
assert abs(d.distance - brute) < 1e-12

fig, ax = plt.subplots(figsize=(6, 3.5))
ax.scatter(part.points[:, 0], part.points[:, 1], s=1, label="part (1000 points)")
ax.scatter(scan.points[:, 0], scan.points[:, 1], s=1, label="scan (5000 points)")
pa, pb = d.point_a, d.point_b
ax.plot([pa[0], pb[0]], [pa[1], pb[1]], "k-", lw=2, label=f"closest pair, {d.distance:.3f} m")
ax.set_aspect("equal")
ax.legend(loc="upper left", fontsize=8)
ax.set_xlabel("x (m)")
ax.set_ylabel("y (m)")
fig.tight_layout()
fig.savefig(out / "closest_points.png", dpi=90)
