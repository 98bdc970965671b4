"""``reachwise bench NAME``: run a benchmark, print its table or JSON."""

from __future__ import annotations

import importlib

import typer
from rich.console import Console
from rich.table import Table

from reachwise.benchmarks import REGISTRY
from reachwise.benchmarks._harness import BenchReport
from reachwise.errors import UnknownName


def bench(
    name: str = typer.Argument(..., help=f"One of: {', '.join(REGISTRY)}."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
    quick: bool = typer.Option(False, "--quick", help="Fewer samples (smoke run)."),
) -> None:
    """Measure our code and its baseline in one run; print medians, p99 and ratios."""
    if name not in REGISTRY:
        raise UnknownName("reachwise bench", "benchmark", name, REGISTRY)
    module = importlib.import_module(REGISTRY[name])
    report: BenchReport = module.run(quick=quick)
    if json_out:
        typer.echo(report.to_json())
        return
    render(report)


def render(report: BenchReport) -> None:
    """Human output: the same figures as the JSON, as tables."""
    console = Console()
    t = Table(title=f"benchmark {report.benchmark} (µs unless the key says otherwise)")
    t.add_column("metric")
    t.add_column("value", justify="right")
    for k, v in report.metrics.items():
        t.add_row(k, f"{v:.4g}")
    console.print(t)
    if report.ratios:
        r = Table(title="ratios")
        r.add_column("ratio")
        r.add_column("value", justify="right")
        for k, v in report.ratios.items():
            r.add_row(k, f"{v:.3g}")
        console.print(r)
    if report.targets:
        g = Table(title="targets")
        for col in ("target", "value", "limit", "met"):
            g.add_column(col)
        for k, tg in report.targets.items():
            cmp = "≥" if tg.higher_is_better else "≤"
            g.add_row(k, f"{tg.value:.4g}", f"{cmp} {tg.limit:.4g}", "yes" if tg.met else "NO")
        console.print(g)
    for note in report.notes:
        console.print(f"note: {note}")
