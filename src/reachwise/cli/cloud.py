"""``reachwise cloud info|sample|downsample|crop`` and ``reachwise scan``.

Cloud files are read and written by :mod:`reachwise.io.clouds` (PLY, PCD, XYZ/TXT,
CSV, NPY, chosen by suffix). Heavy imports live inside the commands so that
``reachwise --help`` stays fast. Bad input raises a :class:`reachwise.errors.ReachwiseError`
that the entry point prints as one line (exit status 2).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

if TYPE_CHECKING:
    from reachwise.geometry.cloud import PointCloud

app = typer.Typer(
    help="Point clouds: inspect, sample meshes, downsample, crop.", no_args_is_help=True
)

_OUT = typer.Option(..., "--out", "-o", help="Output cloud file (.ply .pcd .xyz .txt .csv .npy).")
_ASCII = typer.Option(False, "--ascii", help="Write PLY/PCD as text instead of binary.")
_MAX_POINTS = typer.Option(
    50_000_000, "--max-points", min=1,
    help="Refuse a cloud file declaring or holding more points than this.",
)  # fmt: skip


def _summary(cloud: PointCloud) -> dict[str, Any]:
    import numpy as np

    lo, hi = cloud.bounds
    return {
        "points": len(cloud),
        "frame": cloud.frame,
        "min": lo.tolist(),
        "max": hi.tolist(),
        "extent": (hi - lo).tolist(),
        "centroid": np.mean(cloud.points, axis=0).tolist(),
    }


def _fmt(v: list[float]) -> str:
    return "(" + ", ".join(f"{x:.4f}" for x in v) + ")"


def _wrote(path: Path, cloud: PointCloud, what: str) -> None:
    typer.echo(f"wrote {path}: {len(cloud)} points ({what})")


@app.command("info")
def info(
    file: Annotated[Path, typer.Argument(help="Cloud file to inspect.")],
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
    drop_non_finite: bool = typer.Option(
        False, "--drop-non-finite", help="Skip rows with NaN/inf coordinates instead of failing."
    ),
    max_points: int = _MAX_POINTS,
) -> None:
    """Show point count, bounds, extent, centroid and nearest-neighbour spacing."""
    import numpy as np
    from scipy.spatial import cKDTree

    from reachwise.io.clouds import cloud_format, load_cloud

    cloud = load_cloud(file, drop_non_finite=drop_non_finite, max_points=max_points)
    out: dict[str, Any] = {"file": str(file), "format": cloud_format(file)}
    out.update(_summary(cloud))
    if len(cloud) > 1:
        dist, _ = cKDTree(cloud.points).query(cloud.points, k=2)
        nn = dist[:, 1]
        out["spacing"] = {
            "min": float(nn.min()),
            "median": float(np.median(nn)),
            "max": float(nn.max()),
        }
    else:
        out["spacing"] = None
    if as_json:
        typer.echo(json.dumps(out))
        return
    typer.echo(f"{out['file']} ({out['format']}): {out['points']} points, frame {out['frame']}")
    typer.echo(f"  min      {_fmt(out['min'])} m")
    typer.echo(f"  max      {_fmt(out['max'])} m")
    typer.echo(f"  extent   {_fmt(out['extent'])} m")
    typer.echo(f"  centroid {_fmt(out['centroid'])} m")
    if out["spacing"] is not None:
        sp = out["spacing"]
        typer.echo(
            f"  nearest-neighbour spacing: min {sp['min']:.4f}, median {sp['median']:.4f}, "
            f"max {sp['max']:.4f} m"
        )


@app.command("sample")
def sample(
    mesh: Annotated[Path, typer.Argument(help="Mesh file (STL, OBJ, PLY, OFF, glTF).")],
    points: int = typer.Option(1000, "--points", "-n", help="Points to sample (thesis: 1000)."),
    out: Path = _OUT,
    seed: int = typer.Option(0, "--seed", help="Random seed (same seed, same points)."),
    scale: float = typer.Option(1.0, "--scale", help="Multiply mesh coordinates (0.001: mm)."),
    ascii: bool = _ASCII,
) -> None:
    """Sample a mesh surface uniformly (area-weighted) into a point cloud."""
    from reachwise.io.clouds import load_mesh_cloud, save_cloud

    cloud = load_mesh_cloud(mesh, n=points, seed=seed, scale=scale)
    _wrote(save_cloud(cloud, out, ascii=ascii), cloud, f"sampled from {mesh}, seed {seed}")


@app.command("downsample")
def downsample(
    file: Annotated[Path, typer.Argument(help="Cloud file to thin.")],
    voxel: float = typer.Option(0.03, "--voxel", help="Voxel edge in metres (P-V: 0.03)."),
    out: Path = _OUT,
    ascii: bool = _ASCII,
    max_points: int = _MAX_POINTS,
) -> None:
    """Keep one point per occupied voxel (the point nearest the voxel's centroid)."""
    from reachwise.geometry.cloud import voxel_downsample
    from reachwise.io.clouds import load_cloud, save_cloud

    cloud = load_cloud(file, max_points=max_points)
    thin = voxel_downsample(cloud, voxel)
    _wrote(save_cloud(thin, out, ascii=ascii), thin, f"from {len(cloud)}, voxel {voxel} m")


@app.command("crop")
def crop(
    file: Annotated[Path, typer.Argument(help="Cloud file to crop.")],
    lo: tuple[float, float, float] = typer.Option(
        ..., "--min", help="Box min corner: X Y Z (m).", metavar="X Y Z"
    ),
    hi: tuple[float, float, float] = typer.Option(
        ..., "--max", help="Box max corner: X Y Z (m).", metavar="X Y Z"
    ),
    out: Path = _OUT,
    ascii: bool = _ASCII,
    max_points: int = _MAX_POINTS,
) -> None:
    """Keep the points inside an axis-aligned box (bounds included)."""
    from reachwise.geometry.cloud import crop as crop_cloud
    from reachwise.io.clouds import load_cloud, save_cloud

    cloud = load_cloud(file, max_points=max_points)
    kept = crop_cloud(cloud, lo, hi)
    _wrote(save_cloud(kept, out, ascii=ascii), kept, f"of {len(cloud)} inside the box")


def scan(
    scene: str = typer.Argument(
        ..., help="Built-in scene name: p5-floor-obstacle or p5-occlusion."
    ),
    out: Path = _OUT,
    noise: float = typer.Option(0.0, "--noise", help="Range noise standard deviation (m)."),
    seed: int = typer.Option(0, "--seed", help="Random seed for the range noise."),
    raw: bool = typer.Option(
        False, "--raw", help="Write every return; skip the crop and voxel downsampling."
    ),
    coarsen: float = typer.Option(
        1.0, "--coarsen", help="Multiply beam and line spacing (quick previews)."
    ),
    occlusion_depth: float | None = typer.Option(
        None,
        "--occlusion-depth",
        min=0.0,
        help="Occlusion-aware: fill the unseen space up to this depth (m) behind every "
        "return with virtual points (treated as occupied).",
    ),
    as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
    ascii: bool = _ASCII,
) -> None:
    """Simulate the P-V laser scanner over a scene and write the cloud.

    By default the scan is cropped to the scene's working area and downsampled to
    3 cm voxels, as in P-V §IV (about 5500 points for p5-floor-obstacle). With
    ``--occlusion-depth`` the space behind the scanned surfaces that no beam saw is
    filled with virtual points (P-V Fig. 5's occlusion gap closed), at the cloud's
    resolution, down to the scene's floor.
    """
    import numpy as np

    from reachwise.geometry.cloud import PointCloud
    from reachwise.geometry.occlusion import OcclusionFill
    from reachwise.geometry.scan_scene import scan_scene
    from reachwise.io.clouds import save_cloud
    from reachwise.sim.p5_scenes import get_scene

    sc = get_scene(scene)
    fill = OcclusionFill(occlusion_depth) if occlusion_depth else None
    raw_scan, processed = scan_scene(sc, seed, noise=noise, coarsen=coarsen, occlusion=fill)
    virtual = 0
    if raw:
        cloud = raw_scan.cloud
        if fill is not None:
            extra = sc.virtual_points(raw_scan, fill)
            virtual = len(extra)
            if virtual:
                cloud = PointCloud(np.concatenate([cloud.points, extra]), name=cloud.name)
    else:
        cloud = processed
    path = save_cloud(cloud, out, ascii=ascii)
    summary: dict[str, Any] = {
        "scene": sc.name,
        "file": str(path),
        "rays": raw_scan.n_rays,
        "returns": len(raw_scan.cloud),
        "points": len(cloud),
        "processed": not raw,
        "noise": noise,
        "seed": seed,
        "crop_min": sc.crop_min.tolist(),
        "crop_max": sc.crop_max.tolist(),
        "voxel": sc.voxel,
        "occlusion_depth": occlusion_depth if fill is not None else None,
    }
    if raw and fill is not None:
        summary["virtual"] = virtual
    if as_json:
        typer.echo(json.dumps(summary))
        return
    what = "raw returns" if raw else f"cropped, {sc.voxel * 100:g} cm voxels"
    if fill is not None:
        what += f", occlusion fill {fill.depth:g} m"
    typer.echo(f"scanned {sc.name}: {raw_scan.n_rays} beams, {len(raw_scan.cloud)} returns")
    _wrote(path, cloud, what)
