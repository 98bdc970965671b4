"""The HTML report of a dimensional synthesis (P-I §4: Tables 3–4, Figs. 5–6)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

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
from reachwise.report.png import save_png

if TYPE_CHECKING:
    from reachwise.kinematics.robot import Robot
    from reachwise.synthesis.synthesize import SynthesisResult

FigureSource = Any  # a matplotlib Figure, PNG bytes or a PNG file path

_FIGURES = {
    "configurations": "The optimized design at every other task point, coloured by status: "
    "green — pose reached, blue — position only, yellow — orientation only, red — neither "
    "(P-I Figs. 4–5 colours).",
    "lci": "LCI at every task point, initial and optimized design (P-I Fig. 6); GCI is its "
    "mean (P-II Eq. 38), KCI its minimum (Eq. 39).",
    "clearance": "The same configurations coloured by each pose's smallest clearance of the "
    "design bodies (watched pairs and bodies against the tunnel); a pose below the required "
    "clearance is red.",
}


def synthesis_figures(result: SynthesisResult) -> dict[str, FigureSource]:
    """Draw the report's figures from the result (P-I Figs. 5–6)."""
    from reachwise.report.plots import clearance_figure, configurations_figure, lci_figure

    best = result.best
    prob = result.problem
    out = {
        "configurations": configurations_figure(
            best.robot, best.q, prob.task.poses, best.status, every=2
        ),
    }
    if best.clearance is not None:
        out["clearance"] = clearance_figure(
            best.robot, best.q, prob.task.poses, best.clearance, result.clearance, every=2
        )
    out["lci"] = lci_figure(
        best.lci_initial, best.lci_final, f"{prob.template.name} on {prob.task.name}"
    )
    return out


def save_synthesis_figures(result: SynthesisResult, folder: str | Path) -> dict[str, Path]:
    """Write ``configurations.png`` and ``lci.png`` (P-I Figs. 5–6) into ``folder``;
    return their paths by figure name."""
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    paths = {}
    for name, fig in synthesis_figures(result).items():
        paths[name] = out / f"{name}.png"
        save_png(fig, paths[name], dpi=110)
    return paths


def _deg(x: float) -> str:
    return num(math.degrees(x), 2)


def dh_rows(template: Robot, found: Robot) -> list[list[object]]:
    """Per joint: type and ``a, α, d, θ``; a design parameter shows ``template → found``
    (modified DH: row ``i`` holds ``a_{i-1}, α_{i-1}, d_i, θ_i``, P-I Table 1)."""
    free = {(j, p) for kind, j, p in template.design.free if kind == "joint"}
    rows: list[list[object]] = []
    for i, (jt, jf) in enumerate(zip(template.joints, found.joints, strict=True)):
        cells: list[object] = [i + 1, jt.type + (" (passive)" if jt.passive else "")]
        for p in ("a", "alpha", "d", "theta"):
            f = _deg if p in ("alpha", "theta") else (lambda v: num(v, 4))
            vt, vf = getattr(jt, p), getattr(jf, p)
            cells.append(f"{f(vt)} → {f(vf)}" if (i, p) in free else f(vf))
        rows.append(cells)
    return rows


def design_rows(result: SynthesisResult) -> list[list[object]]:
    """Per design parameter: bounds, template value, the best run's value."""
    prob = result.problem
    lo, hi = prob.bounds
    t0 = prob.design_vector(prob.template)
    d = result.best.design
    return [
        [n, num(lo[k]), num(hi[k]), num(t0[k]), num(d[k]), num(d[k] - t0[k])]
        for k, n in enumerate(prob.design_names)
    ]


def _table3(result: SynthesisResult, with_thesis: bool) -> Raw:
    from reachwise.report.design import bound_flag

    hits = [h.as_dict() for h in result.bound_hits()]
    head = ["parameter", "initial", "optimized", "changed %"]
    if with_thesis:
        head += ["thesis initial", "thesis optimized", "thesis changed %"]
    head += ["bound flag"]
    rows = []
    for r in result.table3():
        row: list[object] = [
            r["parameter"],
            num(r["initial"]),
            num(r["optimized"]),
            num(r["changed_percent"], 2),
        ]
        if with_thesis:
            a, b, c = thesis.P1_TABLE3[str(r["parameter"])]
            row += [num(a), num(b), num(c, 2)]
        rows.append([*row, bound_flag(hits, str(r["parameter"])) or "–"])
    cap = (
        "Normalized design parameters of the best run: 0 and 1 are each parameter's "
        "bounds (P-I Table 3). Bound flag: the parameter ended at, or within 1 % of its "
        "range from, a bound (or its minimum length)."
    )
    if with_thesis:
        cap += (
            " Thesis columns: P-I Table 3, one run on the real SB60 and the 10 real drill "
            "plans, starting from the real boom's dimensions; ours starts from the run's "
            "Beta-sampled design, and our template, bounds and task are public stand-ins, so "
            "the values are not expected to agree, only the kind of result."
        )
    return table(head, rows, caption=cap, id="table3")


def _table4(result: SynthesisResult, with_thesis: bool) -> Raw:
    head = ["parameter", "mean", "std", "runs"]
    if with_thesis:
        head += ["thesis mean", "thesis std"]
    rows = []
    for r in result.table4():
        row: list[object] = [r["parameter"], num(r["mean"]), num(r["std"]), r["runs"]]
        if with_thesis:
            m, s = thesis.P1_TABLE4[str(r["parameter"])]
            row += [num(m), num(s)]
        rows.append(row)
    n_ok = sum(bool(r.reached.all()) for r in result.runs)
    over = "the runs that reached every point" if n_ok else "all runs (none reached every point)"
    cap = f"Mean and standard deviation of the normalized design over {over} (P-I Table 4)."
    if with_thesis:
        cap += f" Thesis columns: P-I Table 4, {thesis.P1_RUNS} runs."
    return table(head, rows, caption=cap, id="table4")


def _runs(result: SynthesisResult) -> Raw:
    from reachwise.kinematics.indices import gci, kci

    K = result.problem.K
    rows, cls = [], []
    for i, r in enumerate(result.runs):
        rows.append(
            [
                r.seed,
                f"{r.n_reached}/{K}",
                num(r.e_obj, 6),
                r.iterations,
                yes_no(r.converged),
                num(gci(r.lci_final)),
                num(kci(r.lci_final)),
                num(float(r.position_error.max()) * 1e3, 3),
                num(float(r.orientation_error.max()) * 1e3, 3),
            ]
        )
        cls.append("good" if i == result.best_index else "")
    return table(
        [
            "seed",
            "reached",
            "e_obj",
            "iterations",
            "converged",
            "GCI",
            "KCI",
            "max position error (mm)",
            "max orientation error (mrad)",
        ],
        rows,
        caption="Every run from its own seed (Beta-sampled initial design and IK-seeded "
        "joints). e_obj: sum over the points of the pose error norm; the best run "
        "(most points reached, then smallest e_obj) is highlighted.",
        id="runs",
        row_class=cls,
    )


def _points(result: SynthesisResult) -> Raw:
    best = result.best
    task = result.problem.task
    rows = [
        [
            k,
            task.names[k],
            task.groups[k],
            int(task.dims[k]),
            num(best.position_error[k] * 1e3, 3),
            num(best.orientation_error[k] * 1e3, 3),
            best.status[k],
            num(best.lci_initial[k]),
            num(best.lci_final[k]),
        ]
        for k in range(result.problem.K)
    ]
    return table(
        [
            "#",
            "name",
            "group",
            "dims",
            "position error (mm)",
            "orientation error (mrad)",
            "status",
            "LCI initial",
            "LCI optimized",
        ],
        rows,
        id="points",
        left=(1, 2, 6),
        row_class=["" if s == "full" else "bad" for s in best.status],
    )


def clearance_section(result: SynthesisResult, data: Mapping[str, Any]) -> Raw | None:
    """The bodies' clearance: what was required, the poses left out before the solve
    (with why), and every pose's smallest clearance and the pair it belongs to; None
    without a clearance."""
    c = data.get("clearance")
    if not c:
        return None
    required = float(c["required_m"])
    parts: list[Raw] = [
        para(
            f"Every watched pair of design bodies, and every body against the tunnel, kept "
            f"at least {required:g} m apart at every pose, as constraints of the solve. "
            + (
                f"Smallest clearance over the task: {c['smallest_m']:.3f} m."
                if c["smallest_m"] is not None
                else ""
            )
        )
    ]
    if c["unservable"]:
        parts.append(
            table(
                ["pose", "why no design can serve it"],
                [[u["name"], u["reason"]] for u in c["unservable"]],
                caption=f"{len(c['unservable'])} poses left out before the solve.",
                id="unservable",
                left=(0, 1),
            )
        )
    rows = [[r["name"], num(r["clearance_m"]), " ~ ".join(r["pair"])] for r in c["per_pose"]]
    if rows:
        cls = ["bad" if r["clearance_m"] < required else "" for r in c["per_pose"]]
        parts.append(
            details(
                "every pose's smallest clearance",
                table(
                    ["pose", "smallest clearance (m)", "pair"],
                    rows,
                    id="clearance-table",
                    left=(0, 2),
                    row_class=cls,
                ),
            )
        )
    return section("Clearance of the design bodies", *parts, id="clearance")


def _comparison(result: SynthesisResult, data: Mapping[str, Any]) -> Raw:
    ok = data["runs_reaching_all"]
    rows: list[tuple[object, object, object, object]] = [
        (
            "task points",
            f"{thesis.P1_POINTS} (10 real drill plans combined)",
            f"{data['task_points']} ({data['task']})",
            "ours: public stand-in plans",
        ),
        (
            "unknowns optimized",
            "“several hundreds” (design + base + joints per point)",
            data["unknowns"],
            "design parameters + base + joint values at every point",
        ),
        (
            "runs reaching every point",
            f"{thesis.P1_RUNS} of {thesis.P1_RUNS}: “in each "
            "case, the optimization method finds the minimum”",
            f"{ok} of {data['runs']}",
            "within 1 mm / 1 mrad",
        ),
        (
            "largest normalized std over runs (Table 4)",
            num(max(s for _, s in thesis.P1_TABLE4.values())),
            num(max(float(r["std"]) for r in result.table4())),
            "the solutions are “similar”: spread of the found designs",
        ),
    ]
    return comparison(rows, "thesis-synthesis")


def synthesis_html(
    result: SynthesisResult,
    figures: Mapping[str, FigureSource] | None = None,
    extra: Sequence[Raw] = (),
) -> str:
    """The report of ``result`` as an HTML string; ``figures`` (name → Figure, PNG
    bytes or PNG file) are embedded, ``None`` embeds none; ``extra`` sections (e.g. a
    Pareto front, ``report.design``) follow the design tables."""
    from reachwise.report.design import bounds_section, objective_section
    from reachwise.results.synthesis_out import summary

    data = summary(result)
    prob = result.problem
    task = prob.task
    tmpl = prob.template
    b = data["best"]
    with_thesis = set(prob.design_names) == set(thesis.P1_TABLE3)
    body: list[Raw] = [_summary_section(result, data)]
    objectives = objective_section(result, data)
    clear = clearance_section(result, data)
    body += [s for s in (objectives, clear, bounds_section(data)) if s is not None]
    if with_thesis:
        body.append(
            section(
                "The thesis and this run",
                para(f"Source: {thesis.SOURCES['P-I']}. {thesis.CAVEAT}"),
                _comparison(result, data),
                id="thesis",
            )
        )
    body += [
        section("Normalized design (P-I Table 3)", _table3(result, with_thesis)),
        section("Over the runs (P-I Table 4)", _table4(result, with_thesis)),
        section(
            "DH parameters: template → found",
            table(
                ["frame", "type", "a_{i-1} (m)", "α_{i-1} (°)", "d_i (m)", "θ_i (°)"],
                dh_rows(tmpl, result.robot),
                caption="Modified DH (Craig). A design parameter shows template → found; "
                "θ of a revolute and d of a prismatic joint are offsets added to q.",
                id="dh",
                left=(1,),
            ),
            table(
                ["parameter", "lower", "upper", "template", "found", "change"],
                design_rows(result),
                caption="Design parameters and base position (m, rad) within their bounds.",
                id="design",
            ),
        ),
        *extra,
        section("Runs (convergence)", _runs(result), id="per-run"),
        section(
            "Task points",
            para(
                f"{b['reached']} of {len(task)} points reached within tolerance by the best "
                "run; rows not reached are red.",
            ),
            details("every task point", _points(result)),
        ),
    ]
    figs = _figure_section(figures)
    if figs is not None:
        body.append(figs)
    return page(
        f"Synthesis: {tmpl.name} for {task.name}",
        "Task-based dimensional synthesis (thesis §2, P-I)",
        body,
    )


def _summary_section(result: SynthesisResult, data: Mapping[str, Any]) -> Raw:
    """The report's first section: the task, the template, the problem, the runs and
    the best run's reach, errors and indices (``data``: ``results.synthesis_out.summary``)."""
    prob = result.problem
    task = prob.task
    tmpl = prob.template
    b = data["best"]
    dims = dict(zip(*np.unique(task.dims, return_counts=True), strict=True))
    return section(
        "Summary",
        key_values(
            {
                "task": f"{task.name}: {len(task)} points ("
                + ", ".join(f"{c} × {d}-D" for d, c in dims.items())
                + ")",
                "template robot": f"{tmpl.name}: {len(tmpl.joints)} joints, {tmpl.n} joint "
                f"variables, {len(prob.design_names)} design parameters",
                "problem": f"{data['unknowns']} unknowns, {data['residuals']} residuals; "
                f"solver {data['solver']}",
                "locked joints": ", ".join(f"q{k}" for k in data["locked_joints"]) or "none",
                "runs": f"{data['runs']} (seeds {result.runs[0].seed}…{result.runs[-1].seed}); "
                f"{data['runs_reaching_all']} reach every point",
                "best run": f"seed {data['best_seed']}: {b['reached']}/{len(task)} points "
                f"reached, e_obj {b['e_obj']:.4g}, max errors "
                f"{b['max_position_error_m'] * 1e3:.3f} mm / "
                f"{b['max_orientation_error_rad'] * 1e3:.3f} mrad",
                "GCI (mean LCI)": f"{b['gci_initial']:.4f} → {b['gci']:.4f}",
                "KCI (worst LCI)": f"{b['kci_initial']:.4f} → {b['kci']:.4f}",
                "status of the points": ", ".join(
                    f"{k} {v}" for k, v in b["status_counts"].items()
                ),
            }
        ),
        id="summary",
    )


def _figure_section(figures: Mapping[str, FigureSource] | None) -> Raw | None:
    if figures is None:
        return section("Figures", para("Figures were not drawn (--no-figures).", "note"))
    parts = [figure(src, _FIGURES.get(name, name)) for name, src in figures.items()]
    return section("Figures", *parts, id="figures") if parts else None


def write_synthesis_report(
    result: SynthesisResult,
    folder: str | Path,
    figures: Mapping[str, FigureSource] | bool = True,
    extra: Sequence[Raw] = (),
) -> Path:
    """Write ``folder/report.html`` for ``result``. ``figures``: ``True`` draws them,
    ``False`` leaves them out, a mapping embeds those (e.g. the PNGs just written);
    ``extra``: further sections (``synthesis_html``)."""
    figs = synthesis_figures(result) if figures is True else (figures or None)
    return write_page(Path(folder) / "report.html", synthesis_html(result, figs, extra))
