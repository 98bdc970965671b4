"""The HTML report of a simulation run (thesis §3.3; P-III Fig. 3, P-V Figs. 3–5)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

import reachwise.report.thesis as thesis
from reachwise.report.html import (
    Raw,
    comparison,
    details,
    figure,
    key_values,
    num,
    page,
    para,
    section,
    table,
    write_page,
    yes_no,
)

if TYPE_CHECKING:
    from reachwise.sim.log import SimulationLog
    from reachwise.sim.scenarios import Scenario

FigureSource = Any  # a matplotlib Figure, PNG bytes or a PNG file path

_FIGURES = {
    "joints": "Joint values against time with collision avoidance (left) and without it "
    "(right); the dashed line and grey area mark the baseline's first collision and what "
    "follows it (P-III Fig. 3a/3b).",
    "min_distance": "Smallest signed distance over every watched pair against time, with "
    "(solid) and without (dashed) avoidance; dotted: the collision margins; below 0 the "
    "solids overlap.",
    "tool_path": "Tool paths over the scanned environment cloud, top and side view; "
    "dashed: without avoidance (P-V Figs. 4–5).",
}
_LABELS = {
    "avoidance": "with avoidance",
    "baseline": "without avoidance (baseline)",
    "reference": "reference plant",
}


def scene_cloud(scenario: Scenario | str | Path) -> NDArray[np.float64] | None:
    """Every environment object's cloud in world coordinates (robot links excluded)."""
    from reachwise.sim.world import build_world

    world = build_world(scenario)
    objs = [o for o in world.scene.objects.values() if "/" not in o.name]
    if not objs:
        return None
    poses = world.scene.poses()
    return np.concatenate(
        [o.cloud.points @ poses[o.name][:3, :3].T + poses[o.name][:3, 3] for o in objs]
    )


def _t(v: float | None) -> str:
    return "not reached" if v is None else f"{v:.2f} s"


def _cm(v: float | None) -> str:
    return "–" if v is None or not math.isfinite(v) else f"{v * 100:.1f} cm"


def leg_lengths(log: SimulationLog, robot: str) -> list[tuple[str, float, float | None]]:
    """Per goal of ``robot``: (name, tool path length from the previous goal (or the
    start) to this one (m), when it was reached); the last leg of an unreached goal
    runs to the end of the log."""
    p = log.tool[robot][:, :3, 3]
    step = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))]
    out = []
    start = 0
    for g in (g for g in log.goals if g.robot == robot):
        end = len(log.t) - 1 if g.reached_at is None else int(np.searchsorted(log.t, g.reached_at))
        end = min(max(end, start), len(log.t) - 1)
        out.append((g.name, float(step[end] - step[start]), g.reached_at))
        if g.reached_at is None:
            break
        start = end
    return out


def outcome_rows(logs: Mapping[str, SimulationLog]) -> list[list[object]]:
    """One row per run: goals, minimum distance, first collision, limits, speeds."""
    rows: list[list[object]] = []
    for label, log in logs.items():
        s = log.summary()
        n = sum(g["reached_at"] is not None for g in s["goals"])
        coll = s["first_collision"]
        rows.append(
            [
                _LABELS.get(label, label),
                s.get("extras", {}).get("plant", "scenario"),
                f"{n}/{len(s['goals'])}",
                _cm(s["min_distance"]),
                "none" if coll is None else f"{coll:.2f} s ({s['first_collision_pair']})",
                yes_no(all(s["limits_held"].values())),
                yes_no(all(s["speeds_held"].values())),
                len(s["stalls"]),
                f"{s['duration']:.2f} s",
            ]
        )
    return rows


def _goals(logs: Mapping[str, SimulationLog]) -> Raw:
    labels = list(logs)
    main = logs[labels[0]]
    rows = []
    for i, g in enumerate(main.goals):
        row: list[object] = [g.robot, g.name]
        for lab in labels:
            gs = logs[lab].goals
            row.append(_t(gs[i].reached_at) if i < len(gs) else "–")
        row += [num(g.position_error * 100, 2), num(g.orientation_error, 4)]
        rows.append(row)
    return table(
        [
            "robot",
            "goal",
            *(f"reached {_LABELS.get(x, x)}" for x in labels),
            "final position error (cm)",
            "final orientation error (rad)",
        ],
        rows,
        caption="Goals in order; errors are those of the first run at the end of its goal.",
        id="goals",
        left=(0, 1),
    )


def _pairs(logs: Mapping[str, SimulationLog]) -> Raw:
    labels = list(logs)
    main = logs[labels[0]]
    rows = []
    for i, p in enumerate(main.pairs):
        row: list[object] = [p, _cm(float(main.margins[i]))]
        for lab in labels:
            log = logs[lab]
            j = log.pairs.index(p) if p in log.pairs else None
            row.append("–" if j is None or not log.t.size else _cm(float(log.signed[:, j].min())))
        rows.append(row)
    return table(
        ["pair", "margin", *(f"min distance {_LABELS.get(x, x)}" for x in labels)],
        rows,
        caption="Smallest signed distance of every watched pair (– when never inside the "
        "monitored range: margin + monitor distance).",
        id="pairs",
        left=(0,),
    )


def _legs(logs: Mapping[str, SimulationLog]) -> Raw:
    rows = []
    for lab, log in logs.items():
        for r in log.robots:
            for name, length, at in leg_lengths(log, r):
                rows.append([_LABELS.get(lab, lab), r, name, num(length, 2), _t(at)])
    return table(
        ["run", "robot", "to goal", "tool path (m)", "reached"], rows, id="legs", left=(0, 1, 2)
    )


def _p3(
    logs: Mapping[str, SimulationLog], scenario: Scenario | None, cloud: NDArray[np.float64] | None
) -> list[tuple[object, object, object, object]]:
    a, b = logs.get("avoidance"), logs.get("baseline")
    rows: list[tuple[object, object, object, object]] = []
    if b is not None:
        ours = (
            "no collision in the simulated " + f"{b.t[-1]:.2f} s"
            if b.first_collision is None
            else f"collides at {b.first_collision:.2f} s ({b.first_collision_pair})"
        )
        rows.append(
            (
                "conventional controller (no avoidance)",
                f"self-collides at {thesis.P3_COLLISION_S:.2f} s (Fig. 3b)",
                ours,
                "feed against the boom's lift part",
            )
        )
    if a is not None:
        g = a.goals[-1] if a.goals else None
        ours = (
            f"goal reached at {_t(g.reached_at if g else None)}, "
            f"{'no collision' if a.first_collision is None else 'COLLIDES'}, min distance "
            f"{_cm(a.summary()['min_distance'])}"
        )
        rows.append(
            (
                "with collision avoidance",
                "the goal is reached without self-collision (Fig. 3a)",
                ours,
                "trajectories modified on the fly, no planning",
            )
        )
    return rows


def _p5(
    logs: Mapping[str, SimulationLog], scenario: Scenario | None, cloud: NDArray[np.float64] | None
) -> list[tuple[object, object, object, object]]:
    a, b = logs.get("avoidance"), logs.get("baseline")
    rows: list[tuple[object, object, object, object]] = []
    if cloud is not None:
        rows.append(
            (
                "scanned cloud",
                f"≈{thesis.P5_SCAN_POINTS} points after 3 cm "
                "downsampling, a gap behind the obstacle (Fig. 3)",
                f"{len(cloud)} points",
                "our nodding-scanner stand-in, with its occlusion gap",
            )
        )
    if scenario is not None:
        pts = [c.points for r in scenario.spec.robots for c in r.link_clouds.values()]
        if pts:
            rows.append(
                (
                    "grabber cloud",
                    f"{thesis.P5_GRABBER_POINTS} points from CAD",
                    f"{pts[0]} points from a mesh",
                    "",
                )
            )
    if b is not None:
        ours = (
            "no collision"
            if b.first_collision is None
            else f"collides at {b.first_collision:.2f} s ({b.first_collision_pair})"
        )
        rows.append(
            ("conventional controller", "the grabber would collide with the obstacle", ours, "")
        )
    if a is not None:
        n = sum(g.reached_at is not None for g in a.goals)
        rows.append(
            (
                "with collision avoidance",
                "a collision-free path to the goal and back (Figs. 4–5)",
                f"{n}/{len(a.goals)} goals, "
                f"{'no collision' if a.first_collision is None else 'COLLIDES'}, min "
                f"distance {_cm(a.summary()['min_distance'])}",
                "",
            )
        )
        for r in a.robots:
            legs = leg_lengths(a, r)
            if len(legs) >= 2:
                rows.append(
                    (
                        "path there vs back",
                        "the way back “is not ideal and contains "
                        "unwanted movements”, from the missing points behind the obstacle",
                        f"{legs[0][1]:.2f} m there, {legs[1][1]:.2f} m back",
                        "tool path lengths",
                    )
                )
    return rows


_THESIS = {"p3-self-collision": ("P-III", _p3), "p5-crane-obstacle": ("P-V", _p5)}


def simulation_html(
    scenario: Scenario,
    logs: Mapping[str, SimulationLog],
    figures: Mapping[str, FigureSource] | None = None,
    cloud: NDArray[np.float64] | None = None,
) -> str:
    """The report of one scenario's runs (``logs``: ``avoidance`` first, then
    ``baseline`` and ``reference`` when run) as HTML."""
    spec = scenario.spec
    main = next(iter(logs.values()))
    body: list[Raw] = [_summary(scenario, logs, cloud)]
    entry = _THESIS.get(main.scenario)
    if entry is not None:
        key, make = entry
        rows = make(logs, scenario, cloud)
        body.append(
            section(
                f"The thesis and this run ({key})",
                para(f"Source: {thesis.SOURCES[key]}. {thesis.CAVEAT}"),
                comparison(rows, "thesis-simulation"),
                id="thesis",
            )
        )
    body += [
        section("Goals", _goals(logs), _legs(logs), id="goals-section"),
        section("Distances", _pairs(logs), id="distances"),
        *_event_sections(logs),
    ]
    if figures is None:
        body.append(section("Figures", para("Figures were not drawn (--no-figures).", "note")))
    elif figures:
        parts = [figure(src, _FIGURES.get(n, n)) for n, src in figures.items()]
        body.append(section("Figures", *parts, id="figures"))
    return page(f"Simulation: {spec.name}", "Collision avoidance (thesis §3.3)", body)


def _summary(
    scenario: Scenario, logs: Mapping[str, SimulationLog], cloud: NDArray[np.float64] | None
) -> Raw:
    """The report's first section: the scenario, its robots and pairs, and each run's
    outcome in one row."""
    spec = scenario.spec
    main = next(iter(logs.values()))
    robots = ", ".join(f"{r.name} ({r.robot}, {r.plant.kind} plant)" for r in spec.robots)
    return section(
        "Summary",
        key_values(
            {
                "scenario": spec.name,
                "description": spec.description or "–",
                "source": scenario.source,
                "robots": robots,
                "time step": f"{spec.dt * 1e3:.1f} ms",
                "watched pairs": f"{len(main.pairs)}, margins "
                + ", ".join(_cm(float(m)) for m in np.unique(main.margins)),
                "environment cloud": "none" if cloud is None else f"{len(cloud)} points",
            }
        ),
        table(
            [
                "run",
                "plant",
                "goals",
                "min distance",
                "first collision",
                "limits held",
                "speeds held",
                "stalls",
                "simulated",
            ],
            outcome_rows(logs),
            id="outcome",
            left=(0, 1, 4),
        ),
        id="summary",
    )


def _event_sections(logs: Mapping[str, SimulationLog]) -> list[Raw]:
    """The runs' stalls, and every event folded away (none when there are none)."""
    out: list[Raw] = []
    stalls = [(lab, e) for lab, log in logs.items() for e in log.events if e.kind == "stalled"]
    if stalls:
        out.append(
            section(
                "Stalls",
                table(
                    ["run", "t (s)", "robot", "what"],
                    [[_LABELS.get(lab, lab), f"{e.t:.2f}", e.robot, e.text] for lab, e in stalls],
                    left=(0, 2, 3),
                ),
            )
        )
    ev = [
        [_LABELS.get(lab, lab), f"{e.t:.2f}", e.robot, e.kind, e.text]
        for lab, log in logs.items()
        for e in log.events
    ]
    if ev:
        out.append(
            section(
                "Events",
                details(
                    f"{len(ev)} events",
                    table(
                        ["run", "t (s)", "robot", "kind", "text"],
                        ev,
                        id="events",
                        left=(0, 2, 3, 4),
                    ),
                ),
            )
        )
    return out


def simulation_figures(
    logs: Mapping[str, SimulationLog], cloud: NDArray[np.float64] | None = None
) -> dict[str, FigureSource]:
    """Draw the report's figures (``report.sim_plots``)."""
    from reachwise.report.sim_plots import joint_figure, min_distance_figure, tool_path_figure

    main = logs["avoidance"] if "avoidance" in logs else next(iter(logs.values()))
    base = logs.get("baseline")
    return {
        "joints": joint_figure(main, base),
        "min_distance": min_distance_figure(main, base),
        "tool_path": tool_path_figure(main, cloud, base),
    }


def write_simulation_report(
    folder: str | Path,
    scenario: Scenario,
    logs: Mapping[str, SimulationLog],
    figures: Mapping[str, FigureSource] | bool = True,
    cloud: NDArray[np.float64] | None = None,
) -> Path:
    """Write ``folder/report.html``. ``figures``: ``True`` draws them, ``False`` leaves
    them out, a mapping embeds those (e.g. the PNGs ``save_figures`` just wrote)."""
    figs = simulation_figures(logs, cloud) if figures is True else (figures or None)
    html = simulation_html(scenario, logs, figs, cloud)
    return write_page(Path(folder) / "report.html", html)
