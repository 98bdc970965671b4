"""Figures of synthesis results, after P-I Figs. 4–6 (matplotlib, Agg backend).

Colours of P-I Fig. 4: red — outside both tolerances, blue — position within
tolerance, yellow — orientation within tolerance, green — the full pose reached.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from reachwise.kinematics.robot import Robot

STATUS_COLOURS = {"neither": "tab:red", "position": "tab:blue", "orientation": "gold",
                  "full": "tab:green"}  # fmt: skip


def _figure(**kw: Any) -> Figure:
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    return Figure(**kw)


def configurations_figure(
    robot: Robot,
    Q: NDArray[np.float64],
    targets: NDArray[np.float64],
    status: Sequence[str],
    every: int = 2,
    title: str = "",
) -> Figure:
    """The manipulator skeleton at every ``every``-th task configuration, coloured by
    the point's status, with the target positions and tool axes (P-I Figs. 4–5)."""
    fig = _figure(figsize=(8, 6))
    ax = fig.add_subplot(projection="3d")
    counts = {s: sum(1 for x in status if x == s) for s in STATUS_COLOURS}
    _skeletons(ax, robot, Q, targets, [STATUS_COLOURS[s] for s in status], every)
    ax.set_title(title or f"{robot.name}: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    return fig


def clearance_figure(
    robot: Robot,
    Q: NDArray[np.float64],
    targets: NDArray[np.float64],
    clearance: NDArray[np.float64],
    required: float,
    every: int = 2,
) -> Figure:
    """The skeletons of ``configurations_figure`` coloured by each pose's smallest
    clearance of the design bodies (m; colour bar), a pose below ``required`` red."""
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    fig = _figure(figsize=(8, 6))
    ax = fig.add_subplot(projection="3d")
    c = np.asarray(clearance, dtype=np.float64)
    finite = c[np.isfinite(c)]
    hi = float(finite.max()) if finite.size else required + 1.0
    norm = Normalize(vmin=required, vmax=max(hi, required + 1e-3))
    cmap = colormaps["viridis"]
    colours = [cmap(norm(v)) if v >= required else "tab:red" for v in c]
    _skeletons(ax, robot, Q, targets, colours, every)
    fig.colorbar(ScalarMappable(norm, cmap), ax=ax, shrink=0.6, label="smallest clearance (m)")
    below = int(np.sum(c < required))
    ax.set_title(
        f"{robot.name}: smallest clearance per pose, {float(c.min()):.3f} m at worst; "
        f"{below} below {required:g} m (red)"
    )
    return fig


def _skeletons(
    ax: Any,
    robot: Robot,
    Q: NDArray[np.float64],
    targets: NDArray[np.float64],
    colours: Sequence[Any],
    every: int,
) -> None:
    """The skeleton at every ``every``-th configuration in its colour, the targets and
    their tool axes, equal axes."""
    F = robot.fk_all(Q)
    for k in range(0, len(Q), max(every, 1)):
        o = F[k, :, :3, 3]
        ax.plot(o[:, 0], o[:, 1], o[:, 2], color=colours[k], lw=0.8, alpha=0.8)
    p = targets[:, :3, 3]
    z = targets[:, :3, 2]
    ax.scatter(p[:, 0], p[:, 1], p[:, 2], s=6, c="k")
    ax.quiver(p[:, 0], p[:, 1], p[:, 2], z[:, 0], z[:, 1], z[:, 2], length=0.4, color="0.4",
              lw=0.5)  # fmt: skip
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    _equal_axes(ax, np.vstack([F[:, :, :3, 3].reshape(-1, 3), p]))


def _equal_axes(ax: Any, pts: NDArray[np.float64]) -> None:
    c = 0.5 * (pts.max(0) + pts.min(0))
    r = 0.5 * float((pts.max(0) - pts.min(0)).max())
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)


def lci_figure(
    lci_initial: NDArray[np.float64], lci_final: NDArray[np.float64], title: str = ""
) -> Figure:
    """LCI at every task point for the initial and the optimized design (P-I Fig. 6)."""
    fig = _figure(figsize=(8, 3.5))
    axes = fig.subplots(1, 2, sharey=True)
    for ax, v, name in zip(axes, (lci_initial, lci_final), ("initial", "optimized"), strict=True):
        ax.bar(np.arange(len(v)), v, color="tab:blue" if name == "initial" else "tab:green")
        ax.set_title(f"{name}: mean {np.mean(v):.3f}, min {np.min(v):.3f}")
        ax.set_xlabel("task point")
    axes[0].set_ylabel("LCI")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig
