"""Write a Pareto sweep (``synthesis.pareto``) to a folder a designer can browse.

``pareto/`` holds ``front.json`` and ``front.csv`` (every design of the sweep: weights,
objective values, reach, whether it is on the front, its bound flags; ``front.json``'s
``partial`` says the sweep was stopped and the front is that of the designs found) and one folder
per design, ``point-K/``, with ``design.yaml`` and ``design.urdf``. The report links
each row to those files.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

from reachwise.io.atomic import atomic_open, atomic_write
from reachwise.io.urdf import export_urdf
from reachwise.results.design_file import save_design
from reachwise.synthesis.objectives import OBJECTIVES
from reachwise.synthesis.pareto import ParetoPoint, ParetoResult


def point_record(p: ParetoPoint, folder: str) -> dict[str, Any]:
    """One design of the sweep as plain data; file links relative to the report."""
    return {
        "index": p.index,
        "weights": {k: float(v) for k, v in p.weights.items()},
        "values": {k: float(v) for k, v in p.values.items()},
        "reached": int(p.reached.sum()),
        "points": int(p.reached.size),
        "all_reached": p.all_reached,
        "front": not p.dominated,
        "bound_hits": [h.as_dict() for h in p.bound_hits],
        "design_yaml": f"{folder}/design.yaml",
        "design_urdf": f"{folder}/design.urdf",
    }


def write_pareto(
    result: ParetoResult, out: str | Path, link_base: str = "pareto", clearance: float = 0.0
) -> dict[str, Any]:
    """Write every design of ``result`` into ``out`` (module docstring); return the data
    (``points``: one record per design, links relative to ``out``'s parent folder).
    ``clearance`` is what the designs' bodies keep (``design_file``)."""
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    records = []
    for p in result.points:
        sub = folder / f"point-{p.index}"
        sub.mkdir(exist_ok=True)
        save_design(p.robot, sub / "design.yaml", clearance)
        export_urdf(p.robot, sub / "design.urdf")
        records.append(point_record(p, f"{link_base}/point-{p.index}"))
    a, b = result.names
    data = {
        "objectives": list(result.names),
        "senses": {n: "max" if OBJECTIVES[n] > 0 else "min" for n in result.names},
        "start": {k: float(v) for k, v in result.start.values.items()},
        "front_size": len(result.front),
        "partial": result.partial,
        "points": records,
    }
    atomic_write(folder / "front.json", json.dumps(data, indent=2))
    with atomic_open(folder / "front.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        names = [n for n in OBJECTIVES if n in result.start.values]
        w.writerow(["index", f"w_{a}", f"w_{b}", *names, "reached", "front", "bound_hits",
                    "design_yaml"])  # fmt: skip
        for r in records:
            w.writerow([r["index"], r["weights"][a], r["weights"][b],
                        *(repr(r["values"][n]) for n in names), r["reached"], r["front"],
                        " ".join(f"{h['parameter']}:{h['side']}" for h in r["bound_hits"]),
                        r["design_yaml"]])  # fmt: skip
    return data
