"""Reach and conditioning of a built-in robot: tool positions of random joint vectors
inside the limits, coloured by the local conditioning index (LCI, P-I Eq. 36-37).

Usage: python examples/workspace.py [OUT_FOLDER]   (writes workspace.png there)
"""

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import reachwise
from reachwise.kinematics import lci

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
robot = reachwise.load_robot("puma560")
rng = np.random.default_rng(0)
q = rng.uniform(robot.lower, robot.upper, size=(2000, robot.n))
tips = np.array([robot.fk(qi)[:3, 3] for qi in q])
conditioning = np.asarray(lci(robot, q))

print(f"{robot.name}: {robot.n} joints, {len(q)} random joint vectors")
print(f"reach: {np.linalg.norm(tips[:, :2], axis=1).max():.3f} m from the base axis")
print(f"LCI: median {np.median(conditioning):.3f}, max {conditioning.max():.3f}")

fig, ax = plt.subplots(figsize=(6, 4.5))
sc = ax.scatter(tips[:, 0], tips[:, 2], c=conditioning, s=4, cmap="viridis")
fig.colorbar(sc, label="LCI")
ax.set_xlabel("x (m)")
ax.set_ylabel("z (m)")
ax.set_aspect("equal")
ax.set_title(f"{robot.name}: tool positions (side view)")
fig.tight_layout()
fig.savefig(out / "workspace.png", dpi=90)
