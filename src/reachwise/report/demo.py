"""The top-level report of ``reachwise demo``: every stage's key figures, the thesis's
numbers next to ours, and links to the per-run reports."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

import reachwise.report.thesis as thesis
from reachwise.report.html import (
    Raw,
    comparison,
    esc,
    key_values,
    link,
    page,
    para,
    section,
    table,
    write_page,
)


class _Stage(Protocol):
    @property
    def key(self) -> str: ...

    @property
    def title(self) -> str: ...


def _cm(v: float | None) -> str:
    return "n/a" if v is None else f"{v * 100:.1f} cm"


def _sim_line(label: str, r: Mapping[str, Any]) -> str:
    coll = r["first_collision_s"]
    return (
        f"{label}: goals {r['goals_reached']}/{r['goals']}, min distance "
        f"{_cm(r['min_distance_m'])}, "
        + ("no collision" if coll is None else f"collides at {coll:.2f} s")
    )


def key_figures(key: str, r: Mapping[str, Any]) -> list[str]:
    """A stage's key figures as short lines (the console summary and the overview)."""
    if key == "task":
        return [
            f"{r['points']} points, equal to the built-in within {r['matches_builtin_m']:.0e} m"
        ]
    if key == "kinematics":
        return [
            f"{n}: IK {v['solved']}/{v['targets']}, {v['median_ik_ms']:.2f} ms"
            for n, v in r.items()
        ]
    if key == "synthesis":
        return [
            f"{r['runs_reaching_all']}/{r['runs']} runs reach all {r['task_points']} points",
            f"best run, random start design → final design: GCI {r['gci_initial']:.4f} → "
            f"{r['gci']:.4f}, KCI {r['kci_initial']:.4f} → {r['kci']:.4f}",
            *(
                [f"conditioning objective, reaching design → improved final design: GCI "
                 f"{r['gci_reach_only']:.4f} → {r['gci']:.4f}"]
                if r.get("gci_reach_only") is not None
                else []
            ),
            *([f"{len(r['bound_hits'])} design parameter(s) at a bound"]
              if r.get("bound_hits") else []),
        ]  # fmt: skip
    if key == "topology":
        out = [f"{len(r['topologies'])} topologies, subset {r['subset']}, top {r['top']}"]
        for row in r["table"]:
            if row["rank"] is not None:
                out.append(f"#{row['rank']} {row['topology']}: mean {row['mean']:.4f}")
        return out
    if key in ("p3", "p5"):
        return [_sim_line(lab, r[lab]) for lab in ("avoidance", "baseline") if lab in r]
    if key == "distance":
        return [
            f"{r['agree_with_brute']}/{r['queries']} equal brute force, median "
            f"{r['median_query_us']:.0f} µs"
        ]
    return []


def headline(done: Mapping[str, Mapping[str, Any]]) -> list[tuple[object, ...]]:
    """The thesis's reported figures next to the demo's, one row per experiment."""
    rows: list[tuple[object, ...]] = []
    s = done.get("synthesis")
    if s is not None:
        rows.append(
            (
                "P-I: runs reaching every drilling pose",
                f"{thesis.P1_RUNS} of {thesis.P1_RUNS} on {thesis.P1_POINTS} points",
                f"{s['runs_reaching_all']} of {s['runs']} on {s['task_points']} points",
                "sb60 stand-in, tunnel-87 stand-in task",
            )
        )
    t = done.get("topology")
    if t is not None:
        rows += _topology_rows(t)
    p3 = done.get("p3")
    if p3 is not None and "baseline" in p3:
        c = p3["baseline"]["first_collision_s"]
        rows.append(
            (
                "P-III: conventional controller",
                f"self-collides at {thesis.P3_COLLISION_S:.2f} s",
                "no collision" if c is None else f"collides at {c:.2f} s",
                "Fig. 3b",
            )
        )
        a = p3["avoidance"]
        rows.append(
            (
                "P-III: with avoidance",
                "goal reached, no self-collision",
                _sim_line("", a).lstrip(": "),
                "Fig. 3a",
            )
        )
    p5 = done.get("p5")
    if p5 is not None and "baseline" in p5:
        rows += _p5_rows(p5)
    return rows


def _topology_rows(t: Mapping[str, Any]) -> list[tuple[object, ...]]:
    """P-II's rows of :func:`headline`: the best topology, and how many have a solution."""
    ours = t["ranked"][0] if t["ranked"] else "none feasible"
    solved = sum(1 for row in t["table"] if row["feasible"])
    n_t = sum(thesis.P2_TABLE2.get(n) is not None for n in t["topologies"])
    best = f"configuration {thesis.P2_BEST[-1]} ({thesis.P2_BEST})"
    return [
        (
            "P-II: best topology by GCI and KCI",
            best,
            ours,
            "ours ranked by the mean of GCI and KCI",
        ),
        (
            "P-II: topologies with a solution",
            f"{n_t} of {len(t['topologies'])}",
            f"{solved} of {len(t['topologies'])}",
            "ours: feasible in the last round each reached",
        ),
    ]


def _p5_rows(p5: Mapping[str, Any]) -> list[tuple[object, ...]]:
    """P-V's rows of :func:`headline`: both controllers, and the scanned cloud's size."""
    rows: list[tuple[object, ...]] = []
    c = p5["baseline"]["first_collision_s"]
    rows.append(
        (
            "P-V: conventional controller",
            "the grabber collides with the obstacle",
            "no collision" if c is None else f"collides at {c:.2f} s",
            "",
        )
    )
    a = p5["avoidance"]
    legs = a.get("legs_m", [])
    there_back = f"; path {legs[0]:.2f} m there, {legs[1]:.2f} m back" if len(legs) > 1 else ""
    rows.append(
        (
            "P-V: with avoidance",
            "collision-free there and back; the way back has unwanted movements (occlusion gap)",
            _sim_line("", a).lstrip(": ") + there_back,
            "Figs. 4–5",
        )
    )
    if p5.get("scan_points") is not None:
        rows.append(
            (
                "P-V: scanned cloud",
                f"≈{thesis.P5_SCAN_POINTS} points",
                f"{p5['scan_points']} points",
                "Fig. 3",
            )
        )
    return rows


def demo_html(
    stages: Sequence[tuple[_Stage, Mapping[str, Any] | None]], figures: Mapping[str, Any]
) -> str:
    """The overview page: one row per stage (status, key figures, time, report link)."""
    rows, cls = [], []
    for st, rec in stages:
        if rec is None:
            status = "interrupted" if figures.get("interrupted") == st.key else "not run"
            rows.append([st.key, st.title, status, "–", "–", "–"])
            cls.append("bad")
            continue
        rep = rec.get("report")
        lines = key_figures(st.key, rec["result"])
        rows.append(
            [
                st.key,
                st.title,
                {"reused": "reused from disk"}.get(rec["status"], rec["status"]),
                Raw("<br>".join(esc(x) for x in lines)),
                f"{rec['elapsed_s']:.1f} s",
                link(rep, rep) if rep else "–",
            ]
        )
        cls.append("")
    done = {st.key: rec["result"] for st, rec in stages if rec is not None}
    body: list[Raw] = [
        section(
            "What ran",
            para(
                "The main job on embedded defaults: the tunnel-87 drilling task, the "
                "dimensional synthesis of the sb60 boom for it, the ranking of the six P-II "
                "topologies (a descriptive subset first, the best on the complete task), and "
                "the P-III and P-V collision-avoidance experiments with and without "
                "avoidance. Each stage's own report holds its tables and figures."
            ),
            key_values(
                {
                    "results folder": figures.get("out", ""),
                    "time": f"{figures.get('stages_s', 0.0):.1f} s computing the stages; this "
                    f"invocation {figures.get('elapsed_s', 0.0):.1f} s (stages complete on disk "
                    "are reused)",
                    "seed": figures.get("seed", ""),
                }
            ),
            table(
                ["stage", "what", "status", "key figures", "time", "report"],
                rows,
                id="stages",
                left=(0, 1, 2, 3, 5),
                row_class=cls,
            ),
            id="overview",
        )
    ]
    head = headline(done)
    if head:
        body.append(
            section(
                "The thesis and this demo",
                para(f"{thesis.CAVEAT} Sources: " + "; ".join(thesis.SOURCES.values()) + "."),
                comparison(head, "thesis-demo"),  # type: ignore[arg-type]
                id="thesis",
            )
        )
    return page("reachwise demo", "Task-based design and collision-free motion", body)


def write_demo_report(
    out: str | Path,
    stages: Sequence[tuple[_Stage, Mapping[str, Any] | None]],
    figures: Mapping[str, Any],
) -> Path:
    """Write ``out/report.html``."""
    return write_page(Path(out) / "report.html", demo_html(stages, figures))
