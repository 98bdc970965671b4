"""``reachwise replay``: a recorded cell (ROS 1 or ROS 2 bag) through the distance
scene; per frame the distance of every watched pair, and the results back into a bag."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import typer
from rich.console import Console

from reachwise.cli._robot_options import LENIENT, PACKAGE_DIRS, TIP, load_with_options

if TYPE_CHECKING:
    from collections.abc import Mapping

    from reachwise.geometry.cloud import PointCloud
    from reachwise.io.ros.replay import ReplayResult
    from reachwise.kinematics.robot import Robot
    from reachwise.viz.replay_view import ReplayClouds


def replay(
    bag: Path = typer.Argument(
        ..., help="The recording: a ROS 1 .bag, a ROS 2 bag folder, or a .db3/.mcap file."
    ),
    robot: str | None = typer.Option(
        None, "--robot", help="Built-in robot name, or a YAML/URDF file (or --scenario)."
    ),
    scenario: str | None = typer.Option(
        None,
        "--scenario",
        help="Take the robot and its link clouds from this scenario (built-in name or "
        "file): a run recorded with `reachwise simulate --bag` replays as it ran.",
    ),
    scenario_robot: str | None = typer.Option(
        None, "--scenario-robot", help="The scenario's robot (default: its first)."
    ),
    tip: str | None = TIP,
    package_dirs: list[Path] = PACKAGE_DIRS,
    lenient: bool = LENIENT,
    joints: str = typer.Option(
        "/joint_states", "--joints", help="sensor_msgs/JointState topic (matched by joint name)."
    ),
    clouds: list[str] = typer.Option(
        ...,
        "--clouds",
        help="Cloud topic: sensor_msgs/PointCloud2 or a depth sensor_msgs/Image (16UC1, "
        "32FC1); repeat for several.",
    ),
    camera_info: list[str] = typer.Option(
        [],
        "--camera-info",
        help="IMAGE_TOPIC=INFO_TOPIC: the CameraInfo of a depth topic (default: its sibling "
        "camera_info topic).",
    ),
    margin: float = typer.Option(
        0.05, "--margin", min=0.0, help="Frames closer than this (m) are reported as near."
    ),
    frame: str = typer.Option(
        "world", "--frame", help="The fixed frame: the robot's base pose is given in it."
    ),
    links: list[str] = typer.Option(
        [], "--link", help="Watch only this link (repeat; default: every link with geometry)."
    ),
    every: float = typer.Option(
        0.0,
        "--every",
        min=0.0,
        help="Least recording time between two frames (s; 0: each joint state).",
    ),
    block: bool = typer.Option(
        True,
        "--block/--no-block",
        help="Hand clouds over blocking, so each frame uses the newest cloud received "
        "(the default; the same on any machine), or not, as a live robot: each frame "
        "uses the newest cloud already indexed (pair with --rate).",
    ),
    rate: float | None = typer.Option(
        None,
        "--rate",
        min=0.001,
        help="Pace the replay at this multiple of the recording's speed (1: as recorded; "
        "default: as fast as possible).",
    ),
    voxel: float | None = typer.Option(
        None, "--voxel", min=0.0, help="Thin each cloud to one point per voxel of this edge (m)."
    ),
    points: int | None = typer.Option(
        None, "--points", min=1, help="Points sampled per link (default: the robot's own)."
    ),
    memory: float | None = typer.Option(
        None,
        "--memory",
        min=0.001,
        help="Fuse the depth-image topics into one scene memory of this voxel edge (m): "
        "the object 'memory' (occupied and shadow voxels; unseen is never free). Needs "
        "--memory-box.",
    ),
    memory_box: str | None = typer.Option(
        None, "--memory-box", help="x0,y0,z0,x1,y1,z1: the memory's box in --frame (m)."
    ),
    tf_tolerance: float = typer.Option(
        0.0,
        "--tf-tolerance",
        min=0.0,
        help="Use a TF edge's first/last transform up to this long (s) beyond its stamps.",
    ),
    out: Path = typer.Option(Path("replay"), "--out", help="Folder for the results."),
    results_bag: str = typer.Option(
        "auto",
        "--results-bag",
        help="The results as a bag in --out: .bag ROS 1, .mcap MCAP, else ROS 2 sqlite3; "
        "'auto': results.bag for a ROS 1 recording, else results.mcap; 'none': none.",
    ),
    json_out: bool = typer.Option(False, "--json", help="Print the summary as JSON."),
    view: bool = typer.Option(
        False,
        "--view",
        help="Then play the replay back in the browser viewer (robot, clouds, closest-point "
        "lines) until Ctrl-C.",
    ),
    port: int = typer.Option(
        8080, "--port", min=0, max=65535, help="With --view: the viewer's port (or the next free)."
    ),
) -> None:
    """Replay a recorded cell: per frame the smallest distance of every watched pair
    (distances.csv, near.csv, summary.json, report.html, a results bag)."""
    from reachwise.distance.scene_memory import MemoryConfig
    from reachwise.errors import InputError
    from reachwise.io.robot_clouds import link_clouds
    from reachwise.io.ros.replay import ReplaySpec, replay_recording
    from reachwise.report.replay import write_replay_outputs

    infos = {}
    for item in camera_info:
        image, sep, info = item.partition("=")
        if not sep or not image or not info:
            raise InputError("--camera-info", item, "expected IMAGE_TOPIC=INFO_TOPIC")
        infos[image] = info
    box = None
    if memory_box is not None:
        try:
            c = [float(v) for v in memory_box.split(",")]
        except ValueError:
            c = []
        if len(c) != 6:
            raise InputError("--memory-box", memory_box, "expected six numbers x0,y0,z0,x1,y1,z1")
        box = ((c[0], c[1], c[2]), (c[3], c[4], c[5]))
    spec = ReplaySpec(
        joints=joints,
        clouds=tuple(clouds),
        margin=margin,
        frame=frame,
        camera_info=infos,
        links=tuple(links) or None,
        every=every,
        block=block,
        rate=rate,
        voxel=voxel,
        tf_tolerance=tf_tolerance,
        memory=None if memory is None else MemoryConfig(voxel=memory),
        memory_box=box,
    )
    if robot is not None and scenario is not None:
        raise InputError("reachwise replay", "--scenario", "give --robot or --scenario, not both")
    if scenario is not None:
        from reachwise.sim.bag_recorder import scenario_robot as robot_of_scenario

        model, carried = robot_of_scenario(scenario, scenario_robot)
    elif robot is not None:
        model = load_with_options(robot, tip, package_dirs, lenient)
        carried = link_clouds(model, points)
    else:
        raise InputError("reachwise replay", "--robot", "give --robot or --scenario")
    console = Console(stderr=True)
    console.print(f"replaying {bag} with {model.name} …")
    kept = None
    if view:
        from reachwise.viz.replay_view import ReplayClouds

        kept = ReplayClouds()
    result = replay_recording(bag, model, spec, link_clouds=carried, on_cloud=kept)
    inputs = {
        "joints": joints,
        "clouds": list(clouds),
        "robot": robot,
        "scenario": scenario,
        "tip": tip,
    }
    summary = write_replay_outputs(
        result, out, inputs, results_bag=None if results_bag == "none" else results_bag
    )
    if json_out:
        typer.echo(json.dumps(summary, indent=2))
    else:
        console.print(
            f"{summary['frames']} frames, smallest distance "
            f"{summary['min_distance'] if summary['min_distance'] is not None else '–'} m, "
            f"{summary['near_frames']} frames closer than {margin:g} m; results in {out}/"
        )
    if view and kept is not None:
        _view(result, model, carried, kept, port, console)


def _view(
    result: ReplayResult,
    robot: Robot,
    link_clouds: Mapping[str, PointCloud],
    kept: ReplayClouds,
    port: int,
    console: Console,
) -> None:
    """Play ``result`` back in the viewer until Ctrl-C."""
    from reachwise.viz.replay_view import ReplayPlayback
    from reachwise.viz.viewer import Viewer

    viewer = Viewer(port=port)
    try:
        ReplayPlayback(viewer, result, robot, link_clouds, kept)
    except BaseException:
        viewer.stop()
        raise
    console.print(f"viewer at {viewer.url} (Ctrl-C to stop)")
    viewer.wait()
