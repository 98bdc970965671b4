"""Write a synthesis result to a folder: design.yaml, design.urdf, summary.json,
points.csv, runs.csv and the figures of P-I Figs. 4–6."""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path
from typing import Any

from reachwise import __version__
from reachwise.kinematics.indices import gci, kci
from reachwise.synthesis.synthesize import SynthesisResult

STATUSES = ("full", "position", "orientation", "neither")


def summary(result: SynthesisResult) -> dict[str, Any]:
    """Key figures of a synthesis as plain JSON-able data."""
    best = result.best
    prob = result.problem
    runs = result.runs
    return {
        "reachwise": __version__,
        "task": prob.task.name,
        "template": prob.template.name,
        "solver": result.solver,
        "task_points": prob.K,
        "unknowns": prob.size,
        "residuals": prob.residual_rows,
        "design_parameters": list(prob.design_names),
        "locked_joints": {str(k): v for k, v in prob.locked.items()},
        "runs": len(runs),
        "runs_reaching_all": sum(bool(r.reached.all()) for r in runs),
        "best_seed": best.seed,
        "best": {
            "reached": best.n_reached,
            "all_reached": bool(best.reached.all()),
            "e_obj": best.e_obj,
            "max_position_error_m": float(best.position_error.max()),
            "max_orientation_error_rad": float(best.orientation_error.max()),
            "iterations": best.iterations,
            "design": dict(zip(prob.design_names, map(float, best.design), strict=True)),
            "gci_initial": gci(best.lci_initial),
            "kci_initial": kci(best.lci_initial),
            "gci": gci(best.lci_final),
            "kci": kci(best.lci_final),
            "status_counts": {s: best.status.count(s) for s in STATUSES},
        },
        "table3": result.table3(),
        "table4": result.table4(),
        "per_run": [
            {
                "seed": r.seed,
                "reached": r.n_reached,
                "e_obj": r.e_obj,
                "iterations": r.iterations,
                "converged": r.converged,
            }
            for r in runs
        ],
    }


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def write_synthesis(result: SynthesisResult, out: str | Path, figures: bool = True) -> Path:
    """Write every output file of ``result`` into folder ``out``; return the folder."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    best = result.best
    prob = result.problem
    best.robot.save(str(folder / "design.yaml"))
    from reachwise.io.urdf import export_urdf

    export_urdf(best.robot, folder / "design.urdf")
    _atomic_write(folder / "summary.json", json.dumps(summary(result), indent=2))
    task = prob.task
    with open(folder / "points.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        qcols = [f"q{i}" for i in range(best.q.shape[1])]
        header = ["index", "name", "group", "dims", "x", "y", "z", "position_error_m",
                  "orientation_error_rad", "status", "lci_initial", "lci_final"]  # fmt: skip
        w.writerow([*header, *qcols])
        for k in range(prob.K):
            p = task.positions[k]
            w.writerow([k, task.names[k], task.groups[k], int(task.dims[k]),
                        *map(repr, map(float, p)), repr(float(best.position_error[k])),
                        repr(float(best.orientation_error[k])), best.status[k],
                        repr(float(best.lci_initial[k])), repr(float(best.lci_final[k])),
                        *map(repr, map(float, best.q[k]))])  # fmt: skip
    if figures:
        fig = _configurations(result)
        fig.savefig(folder / "configurations.png", dpi=110)
        from reachwise.viz.plots import lci_figure

        lci_figure(best.lci_initial, best.lci_final, f"{prob.template.name} on {task.name}") \
            .savefig(folder / "lci.png", dpi=110)  # fmt: skip
    return folder


def _configurations(result: SynthesisResult) -> Any:
    from reachwise.viz.plots import configurations_figure

    best = result.best
    return configurations_figure(
        best.robot, best.q, result.problem.task.poses, best.status, every=2
    )


def design_rows(result: SynthesisResult) -> list[list[str]]:
    """Rows of the normalized design table (P-I Table 3) for printing."""
    return [
        [str(r["parameter"]), f"{r['initial']:.4f}", f"{r['optimized']:.4f}",
         f"{r['changed_percent']:+.2f}"]
        for r in result.table3()
    ]  # fmt: skip
