"""Report sections of design that optimizes: objectives, bound flags, the Pareto front.

Added to the synthesis report (``report_synthesis``): the objectives the design was
improved for and each objective's value before (the reach-only design) and after; every
design parameter that ended at a bound (P-I Table 3's optimum sits inside its bounds —
ours is flagged wherever it does not); and, for a Pareto sweep, the front as a figure and
a table whose rows link to each design's ``design.yaml`` and ``design.urdf``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from reachwise.report.html import Raw, figure, link, num, para, section, table, yes_no
from reachwise.synthesis.objectives import OBJECTIVES

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from reachwise.synthesis.pareto import ParetoResult
    from reachwise.synthesis.synthesize import SynthesisResult

#: what each objective measures, for captions
MEANING: dict[str, str] = {
    "gci": "GCI, mean LCI over the task (P-II Eq. 38), higher is better",
    "kci": "KCI, worst LCI over the task (P-II Eq. 39), higher is better",
    "size": "Σ|a| + Σ|d| of the free length parameters (m), lower is better",
    "limits": "mean squared distance of the joints from mid-range (0 mid, 1 at a limit)",
    "bounds": "bound-margin penalty (0: every parameter the margin inside its bounds)",
    "clearance": "smallest clearance of the design bodies over the task (m), higher is better",
}
SIDE = {"lower": "at lower bound", "upper": "at upper bound", "min_length": "at min length"}


def bound_flag(hits: Sequence[Mapping[str, Any]], name: str) -> str:
    """The flag of parameter ``name`` among ``hits`` (records of ``BoundHit.as_dict``)."""
    for h in hits:
        if h["parameter"] == name:
            return SIDE[str(h["side"])]
    return ""


def bounds_section(data: Mapping[str, Any]) -> Raw:
    """The design parameters at (or within 1 % of) a bound, from ``summary``'s data."""
    hits = data.get("bound_hits", [])
    if not hits:
        return section(
            "Bounds hit",
            para("No design parameter ended within 1 % of its range from a bound."),
            id="bound-hits",
        )
    rows = [[h["parameter"], num(h["value"]), SIDE[h["side"]], num(h["bound"]),
             num(h["normalized"])] for h in hits]  # fmt: skip
    return section(
        "Bounds hit",
        para(
            f"{len(hits)} design parameter(s) ended at, or within 1 % of its range from, a "
            "bound: the task pushed them further than the design section allows. Widen "
            "those bounds, or ask for margin with the bounds objective (design.margin)."
        ),
        table(
            ["parameter", "value", "flag", "bound", "normalized [0..1]"],
            rows,
            caption="Normalized: 0 and 1 are the declared bounds (P-I Table 3's scale).",
            id="bound-hits-table",
        ),
        id="bound-hits",
    )


def objective_section(result: SynthesisResult, data: Mapping[str, Any]) -> Raw | None:
    """Weights and every objective's value, reach-only design → improved design."""
    weights = data.get("objective") or {}
    best = data["best"]
    if not weights:
        return None
    if "reach_only" not in best:
        return section(
            "Design objectives",
            para(
                "Objectives were asked ("
                + ", ".join(f"{k} {v:g}" for k, v in weights.items())
                + ") but the best run did not reach every pose, so its design was not "
                "improved (the improvement keeps every pose reached)."
            ),
            id="objectives",
        )
    before, after = best["reach_only"], best["objective_values"]
    rows = []
    for n in OBJECTIVES:
        if n not in before or n not in after:
            continue  # the clearance, without bodies
        b, a = float(before[n]), float(after[n])
        change = 100.0 * (a - b) / abs(b) if abs(b) > 1e-12 else 0.0
        good = (a - b) * OBJECTIVES[n] >= -1e-12
        rows.append([n, num(weights.get(n, 0.0), 3), num(b), num(a), num(change, 1),
                     yes_no(good), MEANING[n]])  # fmt: skip
    return section(
        "Design objectives",
        para(
            "After every pose was reached, the design was improved in the null space of the "
            "task (P-I §3.2, Eq. 23–25): every accepted step keeps every pose within "
            f"tolerance. {best['improve_iterations']} improvement iterations."
            + (
                " Kept (a constraint: never worse than the reach-only design): "
                + ", ".join(best["kept"])
                + "."
                if best.get("kept")
                else ""
            )
        ),
        table(
            ["objective", "weight", "reach only", "improved", "change %", "better", "meaning"],
            rows,
            caption="Each objective at the best run's reach-only design and at its improved "
            "design; weighted ones drive the improvement, the others are shown for the "
            "trade-off.",
            id="objective-table",
            left=(0, 6),
        ),
        id="objectives",
    )


def pareto_figure(result: ParetoResult) -> Figure:
    """The sweep's designs in the plane of its two objectives, the front joined."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a, b = result.names
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    dom = [p for p in result.points if p.dominated or not p.all_reached]
    front = result.front
    ax.scatter([p.values[b] for p in dom], [p.values[a] for p in dom], c="0.7",
               label="dominated", zorder=2)  # fmt: skip
    ax.plot([p.values[b] for p in front], [p.values[a] for p in front], "o-", c="tab:blue",
            label="non-dominated (front)", zorder=3)  # fmt: skip
    for p in front:
        ax.annotate(str(p.index), (p.values[b], p.values[a]), textcoords="offset points",
                    xytext=(4, 4), fontsize=8)  # fmt: skip
    s = result.start.values
    ax.scatter([s[b]], [s[a]], marker="s", c="tab:red", label="reach-only start", zorder=4)
    ax.set_xlabel(f"{b} ({'lower' if OBJECTIVES[b] < 0 else 'higher'} is better)")
    ax.set_ylabel(f"{a} ({'lower' if OBJECTIVES[a] < 0 else 'higher'} is better)")
    ax.set_title(f"Pareto front: {a} vs {b}, every design reaching every pose")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def _reaching(points: list[dict[str, Any]]) -> str:
    """What the table's designs reach: every one every pose, or how many do (the front
    holds only those)."""
    full = sum(r["reached"] == r["points"] for r in points)
    if full == len(points):
        return "Every design reaches every pose."
    return f"{full} of {len(points)} designs reach every pose; only they may be on the front."


def pareto_section(
    result: ParetoResult, data: Mapping[str, Any], fig: Figure | bytes | None = None
) -> Raw:
    """The front as a figure and a table; every row links to the design's files."""
    a, b = result.names
    rows, cls = [], []
    for r in data["points"]:
        rows.append([
            r["index"], num(r["weights"][a], 3), num(r["weights"][b], 3),
            num(r["values"][a]), num(r["values"][b]), num(r["values"]["kci"]),
            f"{r['reached']}/{r['points']}", yes_no(r["front"]),
            ", ".join(f"{h['parameter']} {SIDE[h['side']]}" for h in r["bound_hits"]) or "–",
            Raw(link(r["design_yaml"], "design.yaml") + " " + link(r["design_urdf"], "urdf")),
        ])  # fmt: skip
        cls.append("good" if r["front"] else "")
    parts: list[Raw] = [
        para(
            f"{len(data['points'])} weightings of {a} and {b} from the reach-only design "
            f"(weights act on relative changes); {data['front_size']} designs are "
            f"non-dominated. {_reaching(data['points'])}"
            + (
                " Partial front: the sweep was interrupted after these designs."
                if data.get("partial")
                else ""
            )
        )
    ]
    if fig is not None:
        parts.append(figure(fig, f"The designs in the ({b}, {a}) plane; the front is joined."))
    parts.append(
        table(
            ["#", f"w {a}", f"w {b}", a, b, "KCI", "reached", "front", "bounds hit", "files"],
            rows,
            caption=f"{MEANING[a]}; {MEANING[b]}.",
            id="pareto-table",
            left=(8, 9),
            row_class=cls,
        )
    )
    return section(f"Pareto front: {a} vs {b}", *parts, id="pareto")
