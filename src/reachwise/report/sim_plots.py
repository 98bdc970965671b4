"""Figures of simulation runs: joint values with and without avoidance (P-III Fig. 3),
tool path with the scanned cloud (P-V Figs. 4–5), minimum distance against time."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from reachwise.report.png import save_png

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from reachwise.sim.log import SimulationLog

__all__ = ["joint_figure", "min_distance_figure", "save_figures", "tool_path_figure"]


def _figure(rows: int = 1, cols: int = 1, size: tuple[float, float] = (8.0, 4.5)) -> Figure:
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, layout="constrained")
    fig.subplots(rows, cols)
    return fig


def joint_figure(log: SimulationLog, baseline: SimulationLog | None = None) -> Figure:
    """Joint values against time per robot: with avoidance (left) and, if given, the
    baseline without it (right), the baseline's first collision marked and the time
    after it shaded (P-III Fig. 3a/3b)."""
    runs = [log] if baseline is None else [log, baseline]
    rows = len(log.robots)
    fig = _figure(rows, len(runs), (5.5 * len(runs), 3.2 * rows))
    axes = np.atleast_2d(np.asarray(fig.axes, dtype=object).reshape(rows, len(runs)))
    for c, run in enumerate(runs):
        for r, name in enumerate(run.robots):
            ax = axes[r, c]
            q = run.q[name]
            labels = [c[len(name) + 1 :] for c in run.joint_columns(name)]
            for k in range(q.shape[1]):
                ax.plot(run.t, q[:, k], lw=1.2, label=labels[k])
            title = "with collision avoidance" if run.avoidance else "without collision avoidance"
            ax.set_title(f"{name}: {title}", fontsize=9)
            ax.set_xlabel("t (s)")
            ax.set_ylabel("q (rad, m)")
            if run.first_collision is not None:
                ax.axvline(run.first_collision, color="k", ls="--", lw=0.8)
                ax.axvspan(run.first_collision, run.t[-1], color="0.85", zorder=0)
                label = f" collides at {run.first_collision:.2f} s"
                ax.text(run.first_collision, ax.get_ylim()[1], label, va="top", fontsize=8)
            ax.grid(alpha=0.3)
        axes[0, c].legend(fontsize=7, ncol=4, loc="lower left")
    return fig


def tool_path_figure(
    log: SimulationLog,
    cloud: NDArray[np.float64] | None = None,
    baseline: SimulationLog | None = None,
) -> Figure:
    """Top view (x–y) and side view (x–z) of every robot's tool path, over the scanned
    cloud if given (P-V Figs. 4–5); the baseline's path dashed."""
    fig = _figure(1, 2, (11.0, 4.8))
    top, side = fig.axes
    if cloud is not None and len(cloud):
        top.scatter(cloud[:, 0], cloud[:, 1], s=1, c="0.6", label="scan")
        side.scatter(cloud[:, 0], cloud[:, 2], s=1, c="0.6")
    for run, ls in ((log, "-"), (baseline, "--")):
        if run is None:
            continue
        for name in run.robots:
            p = run.tool[name][:, :3, 3]
            lab = f"{name} {'avoidance' if run.avoidance else 'baseline'}"
            top.plot(p[:, 0], p[:, 1], ls, lw=1.5, label=lab)
            side.plot(p[:, 0], p[:, 2], ls, lw=1.5)
            top.plot(p[0, 0], p[0, 1], "o", ms=4, color="k")
    top.set_xlabel("x (m)")
    top.set_ylabel("y (m)")
    side.set_xlabel("x (m)")
    side.set_ylabel("z (m)")
    top.set_aspect("equal", adjustable="datalim")
    side.set_aspect("equal", adjustable="datalim")
    top.set_title("tool path, top view", fontsize=9)
    side.set_title("tool path, side view", fontsize=9)
    top.legend(fontsize=7)
    return fig


def min_distance_figure(log: SimulationLog, baseline: SimulationLog | None = None) -> Figure:
    """Smallest signed distance over all watched pairs against time (negative: the
    solids overlap), with the collision margins."""
    fig = _figure(1, 1, (8.0, 3.8))
    ax = fig.axes[0]
    for run, ls in ((log, "-"), (baseline, "--")):
        if run is None:
            continue
        md = run.min_distance
        ax.plot(run.t, np.where(np.isfinite(md), md, np.nan), ls, lw=1.3,
                label="with avoidance" if run.avoidance else "without avoidance")  # fmt: skip
    for m in np.unique(log.margins):
        ax.axhline(m, color="0.5", lw=0.7, ls=":")
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("minimum distance (m)")
    ax.set_title("minimum distance over all watched pairs (dotted: margins)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def save_figures(
    folder: str | Path,
    log: SimulationLog,
    baseline: SimulationLog | None = None,
    cloud: NDArray[np.float64] | None = None,
) -> list[Path]:
    """Write ``joints.png``, ``tool_path.png`` and ``min_distance.png``; return paths."""
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    figs = {
        "joints.png": joint_figure(log, baseline),
        "tool_path.png": tool_path_figure(log, cloud, baseline),
        "min_distance.png": min_distance_figure(log, baseline),
    }
    paths = []
    for name, fig in figs.items():
        p = out / name
        save_png(fig, p, dpi=110)
        paths.append(p)
    return paths


def _leg_metrics(
    p: NDArray[np.float64], a: NDArray[np.float64], b: NDArray[np.float64]
) -> tuple[float, float]:
    """Length of the polyline ``p`` and its largest distance from the line ``a``–``b``."""
    length = float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1))) if len(p) > 1 else 0.0
    d = (b - a) / np.linalg.norm(b - a)
    r = p - a
    perp = r - np.outer(r @ d, d)
    return length, float(np.max(np.linalg.norm(perp, axis=1))) if len(p) else 0.0


def occlusion_paths_figure(
    runs: list[tuple[str, SimulationLog, NDArray[np.float64] | None]],
    robot: str | None = None,
    outward: tuple[int, ...] = (0, 1),
    back: tuple[int, ...] = (2, 3),
    obstacle: NDArray[np.float64] | None = None,
) -> Figure:
    """Outward and return tool paths, top view, one panel per run (P-V Fig. 5): e.g.
    the scan without and with the occlusion fill. ``runs``: ``(title, log, cloud)``
    with the cloud's points (world) or ``None``; ``outward``/``back``: the goal indices
    of each leg; ``obstacle``: ``[min, max]`` corners of the true obstacle, drawn as a
    box outline. The legend gives each leg's length and its peak deviation from the
    straight line between the outward leg's first and last point."""
    fig = _figure(1, len(runs), (5.2 * len(runs), 5.0))
    for ax, (title, log, cloud) in zip(fig.axes, runs, strict=True):
        name = robot or log.robots[0]
        tool = log.tool[name][:, :3, 3]
        gi = log.goal_index[name]
        legs = [tool[np.isin(gi, outward)], tool[np.isin(gi, back)]]
        if cloud is not None and len(cloud):
            above = cloud[cloud[:, 2] > 0.05]
            ax.scatter(above[:, 0], above[:, 1], s=1, c="0.55", label="cloud (above floor)")
        if obstacle is not None:
            lo, hi = np.asarray(obstacle, dtype=float)
            xs = [lo[0], hi[0], hi[0], lo[0], lo[0]]
            ys = [lo[1], lo[1], hi[1], hi[1], lo[1]]
            ax.plot(xs, ys, "k-", lw=1.0, label="true obstacle")
        if len(legs[0]) > 1:
            a, b = legs[0][0], legs[0][-1]
            ax.plot([a[0], b[0]], [a[1], b[1]], ":", color="0.3", lw=0.8)
            for leg, color, label in (
                (legs[0], "tab:blue", "outward"),
                (legs[1], "tab:red", "return"),
            ):
                if len(leg) < 2:
                    continue
                length, dev = _leg_metrics(leg, a, b)
                ax.plot(leg[:, 0], leg[:, 1], color=color, lw=1.6,
                        label=f"{label}: {length:.2f} m, peak deviation {dev:.2f} m")  # fmt: skip
            ax.plot(a[0], a[1], "ko", ms=4)
            ax.plot(b[0], b[1], "ks", ms=4)
        coll = f", collides at {log.first_collision:.1f} s" if log.first_collision else ""
        ax.set_title(f"{title}{coll}", fontsize=9)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower left")
    return fig


def moving_obstacle_figure(log: SimulationLog, baseline: SimulationLog | None = None) -> Figure:
    """A run with moving obstacles: top view of the tool paths and of the moving
    objects' paths (``log.object_poses``), and the minimum distance against time
    with the baseline's (e.g. the static-world controller) dashed."""
    fig = _figure(1, 2, (12.0, 4.8))
    top, dist = fig.axes
    for run, ls in ((log, "-"), (baseline, "--")):
        if run is None:
            continue
        for name in run.robots:
            p = run.tool[name][:, :3, 3]
            top.plot(p[:, 0], p[:, 1], ls, lw=1.4, label=f"{name} tool ({_mode(run)})")
        md = run.min_distance
        dist.plot(run.t, np.where(np.isfinite(md), md, np.nan), ls, lw=1.2, label=_mode(run))
        if run.first_collision is not None:
            dist.axvline(run.first_collision, color="k", lw=0.7, ls="--")
    for obj, poses in log.object_poses.items():
        top.plot(poses[:, 0, 3], poses[:, 1, 3], ":", lw=1.2, label=f"{obj} (centre)")
    dist.axhline(0.0, color="k", lw=0.8)
    dist.axhline(0.02, color="0.5", lw=0.7, ls=":")
    top.set_xlabel("x (m)")
    top.set_ylabel("y (m)")
    top.set_aspect("equal", adjustable="datalim")
    top.legend(fontsize=7)
    top.set_title("paths, top view", fontsize=9)
    dist.set_xlabel("t (s)")
    dist.set_ylabel("minimum distance (m)")
    dist.set_title("minimum distance (dotted: 2 cm)", fontsize=9)
    dist.grid(alpha=0.3)
    dist.legend(fontsize=8)
    return fig


def _mode(run: SimulationLog) -> str:
    if not run.avoidance:
        return "without avoidance"
    return "static world" if run.extras.get("static_world") else "live"


__all__ += ["moving_obstacle_figure", "occlusion_paths_figure"]
