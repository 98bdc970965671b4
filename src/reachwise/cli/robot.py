"""``reachwise robot show|check|export``."""

from __future__ import annotations

import typer

app = typer.Typer(help="Inspect, validate and export robot models.", no_args_is_help=True)
