"""Self-contained HTML reports: one file per synthesis, topology sweep and simulation
run, and the overview of ``reachwise demo``.

Each report is a single ``report.html`` written next to the run's outputs: tables of
the run's figures, the thesis's reported figures next to ours ("thesis says / we
measured", ``reachwise.report.thesis``), and the run's matplotlib figures
embedded as base64 PNG. CSS is inline; there is no external URL and no JavaScript,
so the file opens anywhere, offline, and can be mailed as is. Every string that can
come from user input is HTML-escaped (``reachwise.report.html.esc``).

* :func:`write_synthesis_report` — P-I: summary, Tables 3–4 next to the thesis's, DH
  parameters template → found, per-run convergence, task points, Figs. 5–6;
* :func:`write_topology_report` — P-II: ranking tables of both rounds, Table 2 next to
  ours, GCI/KCI bar chart, the best designs' configurations;
* :func:`write_simulation_report` — thesis §3.3: outcome with and without avoidance,
  goals, distances, P-III Fig. 3 / P-V Figs. 4–5 style figures, the thesis's numbers;
* :func:`write_demo_report` — the demo's overview linking the per-run reports.

Their figures are drawn by ``reachwise.report.plots`` (synthesis, P-I Figs. 4–6)
and ``reachwise.report.sim_plots`` (simulation) and saved by
``reachwise.report.png.save_png``; ``reachwise.report.ranking`` writes a
topology sweep's ranking tables and best designs. This layer sits above ``sim`` and
below ``viz``: it reads results, it never computes them.
"""

from __future__ import annotations

from reachwise.report.demo import write_demo_report
from reachwise.report.simulate import write_simulation_report
from reachwise.report.synthesis import write_synthesis_report
from reachwise.report.topology import write_topology_report

__all__ = [
    "write_demo_report",
    "write_simulation_report",
    "write_synthesis_report",
    "write_topology_report",
]
