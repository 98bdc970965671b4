"""``reachwise cloud info|sample|downsample|crop`` and ``reachwise scan``."""

from __future__ import annotations

import typer

app = typer.Typer(help="Point clouds: inspect, sample meshes, downsample, crop.", no_args_is_help=True)


def scan(scene: str = typer.Argument(..., help="Scene to scan.")) -> None:
    """Simulate the P-V laser scanner over a scene and write the cloud."""
    raise typer.BadParameter("the scanner is not built yet")
