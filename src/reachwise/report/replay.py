"""The HTML report of a replayed recording: the distance of every watched pair over
the recording's time, the margin, and the table of each pair's closest approach."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from reachwise.io.ros.replay import ReplayResult
from reachwise.report.html import figure, key_values, num, page, section, table, write_page

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["distance_figure", "write_replay_outputs", "write_replay_report"]


def distance_figure(result: ReplayResult) -> Figure:
    """Each pair's distance against recording time, with the margin (dotted)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.0, 4.0), layout="constrained")
    ax = fig.subplots()
    t = result.t - (result.t[0] if result.t.size else 0.0)
    for p, name in enumerate(result.pairs):
        ax.plot(t, result.distance[:, p], lw=1.1, label=name)
    ax.axhline(result.margin, color="0.4", lw=0.8, ls=":", label=f"margin {result.margin:g} m")
    near = np.any(result.near, axis=1)
    if near.any():
        ax.plot(t[near], result.min_distance[near], "r.", ms=3, label="closer than the margin")
    ax.set_xlabel("t from the first frame (s)")
    ax.set_ylabel("distance (m)")
    ax.set_title(f"smallest distance per frame of each watched pair ({result.robot})", fontsize=9)
    ax.grid(alpha=0.3)
    if len(result.pairs) <= 12:
        ax.legend(fontsize=7)
    return fig


def write_replay_report(result: ReplayResult, summary: dict[str, Any], path: str | Path) -> Path:
    """``report.html`` of a replay (``summary`` from
    :func:`~reachwise.io.ros.replay_out.replay_summary`)."""
    rows = [
        [
            p["pair"],
            p["frames"],
            num(p.get("min_distance"), 4, " m"),
            num(p.get("at"), 3, " s"),
            p["near_frames"],
            num(p["first_near"], 3, " s") if p["first_near"] is not None else "–",
        ]
        for p in summary["pairs"]
    ]
    body = [
        section(
            "Recording",
            key_values(
                {
                    "bag": result.bag,
                    "robot": result.robot,
                    "fixed frame": result.frame,
                    "frames": summary["frames"],
                    "clouds handed over": summary["clouds_handed_over"],
                    "clouds used": summary["clouds_used"],
                    "margin": f"{result.margin:g} m",
                    "frames closer than the margin": summary["near_frames"],
                }
            ),
        ),
        section(
            "Distances",
            figure(distance_figure(result), "Distance of every watched pair per frame."),
            table(
                ["pair", "frames", "smallest", "at", "near frames", "first near"],
                rows,
                caption="Per pair: the smallest distance, when, and the frames closer "
                "than the margin.",
            ),
        ),
    ]
    return write_page(path, page("Replay", Path(result.bag).name, body))


def write_replay_outputs(
    result: ReplayResult,
    out: str | Path,
    inputs: dict[str, Any],
    *,
    results_bag: str | Path | None = "auto",
) -> dict[str, Any]:
    """Every file of a replay into folder ``out``: ``distances.csv``, ``near.csv``,
    ``summary.json``, ``report.html`` and the results bag ``results_bag`` (relative to
    ``out``; ``.bag``: ROS 1, ``.mcap``: MCAP, else ROS 2 sqlite3; ``"auto"``:
    ``results.bag`` when the recording was a ROS 1 bag, else ``results.mcap``; None:
    none). Returns the summary."""
    from reachwise.io.ros.replay_out import (
        replay_summary,
        write_csv,
        write_results_bag,
        write_summary,
    )

    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    summary = replay_summary(result, inputs)
    write_csv(result, folder / "distances.csv")
    write_csv(result, folder / "near.csv", near_only=True)
    if results_bag == "auto":
        results_bag = "results.bag" if result.ros1 else "results.mcap"
    if results_bag is not None:
        bag = folder / results_bag
        write_results_bag(result, bag)
        summary["results_bag"] = str(bag)
    write_summary(summary, folder / "summary.json")
    write_replay_report(result, summary, folder / "report.html")
    return summary
