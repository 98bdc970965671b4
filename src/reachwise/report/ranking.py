"""Reports of a topology sweep: ranked tables, the best designs, figures (P-II Table 2, Fig. 4).

``write_report(result, out)`` writes into folder ``out``:

* ``ranking.md`` — the final ranked table like P-II Table 2 (GCI, KCI, their mean, and
  manipulability, link length, prismatic joints, points reached), infeasible topologies
  listed unranked with "–" (Table 2's "no solution"), then the round-1 table;
* ``ranking.csv`` — the same rows (final round, then round-1-only topologies);
* ``ranking.json`` — sweep id, task, subset, configuration, both tables, versions;
* ``designs/NN-NAME.yaml`` and ``.urdf`` — the best ``top`` feasible designs (robot file
  and URDF of the optimized dimensions and base frame);
* ``designs/NN-NAME.png`` — each one's configuration at every other task point,
  coloured by status (P-I Fig. 4 colours; P-II Figs. 3–4).
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import re
from pathlib import Path
from typing import Any

from reachwise._version import __version__
from reachwise.io.atomic import atomic_write
from reachwise.io.robot_file import save_robot
from reachwise.report.png import save_png
from reachwise.synthesis.sweep import SweepResult, versions

_FIELDS = ("rank", "topology", "round", "feasible", "reached", "points", "gci", "kci", "mean",
           "manipulability", "length", "prismatic", "e_obj", "best_run", "best_seed", "runs",
           "runs_feasible", "note", "error")  # fmt: skip


def safe_name(name: str) -> str:
    """A file-name-safe form of a topology name (spec strings get a short hash)."""
    s = re.sub(r"[^A-Za-z0-9_.-]+", "", name.replace(" ", "_").replace("(", "").replace(")", ""))
    if s == name:
        return s
    return f"{s[:40]}-{hashlib.sha256(name.encode()).hexdigest()[:8]}"


def _fmt(v: Any, digits: int = 4) -> str:
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.{digits}f}" if abs(v) < 1e4 else f"{v:.4g}"
    return str(v)


def _types(result: SweepResult, name: str) -> str:
    t = result.topologies.get(name)
    return "" if t is None else t.spec.types


def markdown_table(result: SweepResult, rows: list[dict[str, Any]]) -> str:
    """Rows as a Markdown table; infeasible rows show "–" for their indices."""
    head = ["rank", "topology", "joints", "GCI", "KCI", "mean", "manipulability",
            "length (m)", "prismatic", "reached", "runs ok", "note"]  # fmt: skip
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        ok = bool(r["feasible"])
        idx = [r[k] if ok else None for k in ("gci", "kci", "mean", "manipulability", "length")]
        cells = [
            _fmt(r["rank"]),
            f"`{r['topology']}`",
            _types(result, r["topology"]),
            *(_fmt(v) for v in idx[:3]),
            _fmt(idx[3], 1) if idx[3] is not None else "–",
            _fmt(idx[4], 2) if idx[4] is not None else "–",
            _fmt(r["prismatic"]),
            f"{r['reached']}/{r['points']}",
            f"{r['runs_feasible']}/{r['runs']}",
            r["note"],
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def markdown(result: SweepResult) -> str:
    """The report's Markdown text."""
    cfg = result.config
    task = result.task
    sub = (
        "none (one round on the complete task)"
        if result.subset is None
        else (f"{len(result.subset)} descriptive points")
    )
    out = [
        f"# Topology sweep on `{task.name}` ({len(task)} points)\n",
        f"sweep `{result.sweep_id}` · {len(result.topologies)} topologies · subset: {sub} · "
        f"{cfg.runs} runs per topology (seeds {cfg.seed}–{cfg.seed + cfg.runs - 1}) · "
        f"solver {cfg.solver} · ranked by **{cfg.rank_key}** · reachwise {__version__}\n",
        "GCI = mean LCI over the task (P-II Eq. 38), KCI = worst LCI (Eq. 39), mean = "
        "(GCI + KCI)/2 (P-II Table 2); LCI of the length-scaled Jacobian (P-I Eq. 34–37). "
        "A topology whose best run misses a task point is infeasible: listed, not ranked.\n",
        f"## Final ranking (round {result.final.round}: complete task)\n",
        markdown_table(result, result.final.records()),
    ]
    if result.round1 is not None:
        out += [
            f"\n## Round 1 (descriptive subset, {result.round1.task_points} points)\n",
            f"Advanced to the complete task (top {cfg.top} feasible): "
            + (", ".join(f"`{n}`" for n in result.advanced) or "none")
            + "\n",
            markdown_table(result, result.round1.records()),
        ]
    return "\n".join(out)


def csv_text(rows: list[dict[str, Any]]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(_FIELDS), lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: ("" if r[k] is None else repr(r[k]) if isinstance(r[k], float) else r[k])
                    for k in _FIELDS})  # fmt: skip
    return buf.getvalue()


def report_data(result: SweepResult) -> dict[str, Any]:
    """The JSON report: sweep id, task, subset, configuration, tables, versions."""
    from dataclasses import asdict

    return {
        "sweep_id": result.sweep_id,
        "task": result.task.name,
        "task_points": len(result.task),
        "subset": None if result.subset is None else [int(i) for i in result.subset],
        "config": asdict(result.config),
        "topologies": {n: str(t.spec) for n, t in result.topologies.items()},
        "advanced": list(result.advanced),
        "final": result.final.records(),
        "round1": None if result.round1 is None else result.round1.records(),
        "table": result.table(),
        "new_items": result.new_items,
        "stored_items": result.stored_items,
        "stale_items": result.stale_items,
        "versions": versions(),
    }


def write_report(
    result: SweepResult, out: str | Path, top: int | None = None, figures: bool = True
) -> dict[str, Any]:
    """Write the report files (module docstring); return the JSON data plus the paths
    of the exported designs (``designs``)."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write(folder / "ranking.md", markdown(result))
    atomic_write(folder / "ranking.csv", csv_text(result.table()))
    data = report_data(result)
    k = result.config.top if top is None else top
    designs = []
    ddir = folder / "designs"
    for i, name in enumerate(result.ranked()[:k], start=1):
        ddir.mkdir(exist_ok=True)
        robot = result.robot(name)
        stem = ddir / f"{i:02d}-{safe_name(name)}"
        save_robot(robot, stem.with_suffix(".yaml"))
        from reachwise.io.urdf import export_urdf

        export_urdf(robot, stem.with_suffix(".urdf"))
        entry = {"rank": i, "topology": name, "yaml": str(stem.with_suffix(".yaml")),
                 "urdf": str(stem.with_suffix(".urdf"))}  # fmt: skip
        if figures:
            from reachwise.report.plots import configurations_figure

            best = result.final.best_result(name)
            fig = configurations_figure(
                robot, best.q, result.task.poses, best.status, every=2,
                title=f"#{i} {_types(result, name)} {name}"[:90],
            )  # fmt: skip
            save_png(fig, stem.with_suffix(".png"), dpi=100)
            entry["figure"] = str(stem.with_suffix(".png"))
        designs.append(entry)
    data["designs"] = designs
    atomic_write(folder / "ranking.json", json.dumps(data, indent=2))
    return data
