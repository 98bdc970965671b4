"""The HTML report of a topology sweep (P-II Fig. 1 rounds, Table 2 ranking, Figs. 3–4)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

import reachwise.report.thesis as thesis
from reachwise.report.html import (
    Raw,
    comparison,
    figure,
    key_values,
    num,
    page,
    para,
    section,
    table,
    write_page,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from reachwise.synthesis.sweep import SweepResult


def _types(result: SweepResult, name: str) -> str:
    t = result.topologies.get(name)
    return "" if t is None else t.spec.types


def ranking_rows(result: SweepResult, records: Sequence[Mapping[str, Any]]) -> list[list[object]]:
    """Rows of a ranked table (infeasible topologies show "–" for their indices)."""
    rows: list[list[object]] = []
    for r in records:
        ok = bool(r["feasible"])

        def v(key: str, digits: int = 4, r: Mapping[str, Any] = r, ok: bool = ok) -> str:
            return num(r[key], digits) if ok else "–"

        rows.append(
            [
                "–" if r["rank"] is None else r["rank"],
                r["topology"],
                _types(result, r["topology"]),
                v("gci"),
                v("kci"),
                v("mean"),
                v("manipulability", 1),
                v("length", 2),
                "–" if r["prismatic"] is None else r["prismatic"],
                f"{r['reached']}/{r['points']}",
                f"{r['runs_feasible']}/{r['runs']}",
                r["note"],
            ]
        )
    return rows


_HEAD = [
    "rank",
    "topology",
    "joints",
    "GCI",
    "KCI",
    "mean",
    "manipulability",
    "length (m)",
    "prismatic",
    "reached",
    "runs ok",
    "note",
]


def _ranking(result: SweepResult, records: list[dict[str, Any]], id: str, cap: str) -> Raw:
    return table(
        _HEAD,
        ranking_rows(result, records),
        caption=cap,
        id=id,
        left=(1, 2, 11),
        row_class=["" if r["feasible"] else "bad" for r in records],
    )


def _ours(result: SweepResult) -> dict[str, dict[str, Any]]:
    """Each topology's row: the final round's when it advanced, else round 1's."""
    return {r["topology"]: r for r in result.table()}


def _comparison(result: SweepResult) -> Raw | None:
    names = list(result.topologies)
    if not set(names) <= set(thesis.P2_TABLE2):
        return None
    ours = _ours(result)
    rows: list[tuple[object, object, object, object]] = []
    for n in sorted(names):
        t = thesis.P2_TABLE2[n]
        tt = "no solution" if t is None else f"GCI {t[0]:.4f}, KCI {t[1]:.4f}, mean {t[2]:.4f}"
        r = ours.get(n)
        if r is None:
            o, note = "not run", ""
        elif r["feasible"]:
            o = f"GCI {r['gci']:.4f}, KCI {r['kci']:.4f}, mean {r['mean']:.4f}"
            note = (
                f"rank {r['rank']}"
                if r["rank"] is not None
                else f"{r['note']} (round {r['round']}, {r['points']} points)"
            )
        else:
            o = f"no solution: {r['reached']}/{r['points']} points"
            note = f"round {r['round']}"
        rows.append((n, tt, o, note))
    ranked = result.ranked()
    solved = sum(1 for n in names if ours.get(n, {}).get("feasible"))
    t_solved = sum(v is not None for k, v in thesis.P2_TABLE2.items() if k in names)
    rows.append(
        (
            "best by GCI and KCI",
            f"configuration {thesis.P2_BEST[-1]} ({thesis.P2_BEST})",
            ranked[0] if ranked else "none",
            f"ours ranked by {result.config.rank_key}",
        )
    )
    rows.append(
        (
            "topologies solving the task",
            f"{t_solved} of {len(names)}",
            f"{solved} of {len(names)}",
            "ours: feasible in the last round each reached",
        )
    )
    return comparison(rows, "thesis-topology")


def indices_figure(result: SweepResult) -> Figure:
    """GCI and KCI of every topology (bars; hatched: subset round only), with P-II
    Table 2's values as markers where the topology is one of P-II's six."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    ours = _ours(result)
    names = sorted(result.topologies)
    fig = Figure(figsize=(max(6.0, 1.1 * len(names) + 2), 3.8), layout="constrained")
    ax = fig.subplots()
    x = np.arange(len(names))
    w = 0.38
    for k, (key, colour) in enumerate((("gci", "tab:blue"), ("kci", "tab:orange"))):
        vals, hatch = [], []
        for n in names:
            r = ours.get(n)
            ok = r is not None and r["feasible"] and r[key] is not None
            vals.append(float(r[key]) if ok and r is not None else 0.0)
            hatch.append(r is not None and r["round"] == 1 and result.round1 is not None)
        bars = ax.bar(x + (k - 0.5) * w, vals, w, color=colour)
        for b, h in zip(bars, hatch, strict=True):
            if h:
                b.set_hatch("//")
                b.set_alpha(0.6)
        tv = [thesis.P2_TABLE2.get(n) for n in names]
        tx = [x[i] + (k - 0.5) * w for i, t in enumerate(tv) if t is not None]
        ty = [t[k] for t in tv if t is not None]
        if tx:
            ax.plot(tx, ty, "k_", ms=14, mew=2, label="P-II Table 2" if k == 0 else None)
    ax.set_xticks(x, names, rotation=20, ha="right", fontsize=8)
    ax.set_ylabel("index [0, 1]")
    ax.set_title(
        "GCI and KCI per topology (0 bar: no solution; hatched: subset round only)", fontsize=9
    )
    ax.grid(axis="y", alpha=0.3)
    from matplotlib.patches import Patch

    handles = [
        Patch(color="tab:blue", label="GCI (ours)"),
        Patch(color="tab:orange", label="KCI (ours)"),
        *ax.get_legend_handles_labels()[0],
    ]
    ax.legend(handles=handles, fontsize=8)
    return fig


def topology_html(
    result: SweepResult,
    designs: Sequence[Mapping[str, Any]] = (),
    figures: bool = True,
) -> str:
    """The sweep report as HTML; ``designs`` are ``write_report``'s entries (rank,
    topology, yaml, urdf, figure): their figures are embedded."""
    cfg = result.config
    body: list[Raw] = [_summary(result)]
    comp = _comparison(result)
    if comp is not None:
        body.append(
            section(
                "The thesis and this sweep (P-II Table 2)",
                para(f"Source: {thesis.SOURCES['P-II']}. {thesis.CAVEAT}"),
                comp,
                id="thesis",
            )
        )
    body.append(
        section(
            f"Final ranking (round {result.final.round}: complete task)",
            _ranking(
                result,
                result.final.records(),
                "ranking",
                "A topology whose best run misses a task point is infeasible: listed, "
                "not ranked (P-II Table 2's “no solution”).",
            ),
            id="final",
        )
    )
    if result.round1 is not None:
        body.append(
            section(
                f"Round 1 (descriptive subset, {result.round1.task_points} points)",
                _ranking(
                    result,
                    result.round1.records(),
                    "round1",
                    f"Ranked on the subset; the top {cfg.top} feasible advance.",
                ),
            )
        )
    body.append(
        _figures(result, designs)
        if figures
        else section("Figures", para("Figures were not drawn (--no-figures).", "note"))
    )
    return page(
        f"Topology sweep on {result.task.name}",
        "Topology synthesis and ranking (thesis §2.4, P-II)",
        body,
    )


def _summary(result: SweepResult) -> Raw:
    """The report's first section: the task, the topologies, the rounds and runs, the
    ranking key and what this invocation computed."""
    cfg = result.config
    task = result.task
    sub = (
        "none (one round on the complete task)"
        if result.subset is None
        else (
            f"{len(result.subset)} descriptive points (round 1), top {cfg.top} feasible to the "
            f"complete task (round 2)"
        )
    )
    return section(
        "Summary",
        key_values(
            {
                "task": f"{task.name}: {len(task)} points",
                "topologies": f"{len(result.topologies)}",
                "subset": sub,
                "runs": f"{cfg.runs} per topology and round (seeds {cfg.seed}–"
                f"{cfg.seed + cfg.runs - 1}), solver {cfg.solver}",
                "ranked by": f"{cfg.rank_key} (GCI = mean LCI, P-II Eq. 38; KCI = worst "
                "LCI, Eq. 39; mean = (GCI + KCI)/2)",
                "advanced to the complete task": ", ".join(result.advanced) or "none",
                "this invocation": f"{result.new_items} runs done now ({result.stale_items} "
                f"replacing stored runs of other code), {result.stored_items} found in the "
                "results store",
                "sweep id": result.sweep_id,
            }
        ),
        id="summary",
    )


def _figures(result: SweepResult, designs: Sequence[Mapping[str, Any]]) -> Raw:
    """The indices figure and each best design's figure (P-II Figs. 3–4)."""
    parts = [
        figure(
            indices_figure(result),
            "GCI and KCI of every topology next to P-II "
            "Table 2 (black marks) where it is one of P-II's six.",
        )
    ]
    for d in designs:
        if d.get("figure"):
            parts.append(
                figure(
                    Path(d["figure"]),
                    f"#{d['rank']} {d['topology']}: the "
                    "optimized design at every other task point (P-II "
                    "Figs. 3–4; green: pose reached).",
                )
            )
    return section("Figures", *parts, id="figures")


def write_topology_report(
    result: SweepResult,
    folder: str | Path,
    designs: Sequence[Mapping[str, Any]] = (),
    figures: bool = True,
) -> Path:
    """Write ``folder/report.html`` for the sweep (``designs``: see topology_html)."""
    return write_page(Path(folder) / "report.html", topology_html(result, designs, figures))
