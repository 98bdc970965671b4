"""``reachwise replay``: a recorded cell (ROS 1 or ROS 2 bag) through the distance
scene; per frame the distance of every watched pair, and the results back into a bag."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import typer
from rich.console import Console

from reachwise.cli._options import cli, typed_command
from reachwise.cli._robot_options import RobotFileOptions

if TYPE_CHECKING:
    from collections.abc import Mapping

    from reachwise.geometry.cloud import PointCloud
    from reachwise.io.ros.replay import ReplayResult, ReplaySpec
    from reachwise.kinematics.robot import Robot
    from reachwise.viz.replay_view import ReplayClouds, ReplayMemory


@dataclass(frozen=True)
class ReplaySource:
    """What is replayed: the recording ``bag`` and the robot, from ``robot`` (a
    built-in name or file, its link clouds of ``points`` points; ``None``: the
    default) or from ``scenario`` (its ``scenario_robot``, ``None``: the first)."""

    #: The recording: a ROS 1 .bag, a ROS 2 bag folder, or a .db3/.mcap file.
    bag: Path = cli(
        typer.Argument(
            ..., help="The recording: a ROS 1 .bag, a ROS 2 bag folder, or a .db3/.mcap file."
        )
    )
    #: Built-in robot name or robot file; ``None``: from --scenario.
    robot: str | None = cli(
        typer.Option(
            None, "--robot", help="Built-in robot name, or a YAML/URDF file (or --scenario)."
        )
    )
    #: Scenario whose robot and link clouds are taken; ``None``: --robot.
    scenario: str | None = cli(
        typer.Option(
            None,
            "--scenario",
            help="Take the robot and its link clouds from this scenario (built-in name or "
            "file): a run recorded with `reachwise simulate --bag` replays as it ran.",
        )
    )
    #: The scenario's robot; ``None``: its first.
    scenario_robot: str | None = cli(
        typer.Option(None, "--scenario-robot", help="The scenario's robot (default: its first).")
    )
    #: Points per link cloud of --robot; ``None``: the default.
    points: int | None = cli(
        typer.Option(
            None, "--points", min=1, help="Points sampled per link (default: the robot's own)."
        )
    )


@dataclass(frozen=True)
class ReplayTopics:
    """How the recording is read and measured: the ``joints`` topic, the cloud or
    depth-image topics (``clouds``) with their ``camera_info`` pairs, the world
    ``frame``, the ``links`` watched (empty: all), the watch ``margin`` (m), a frame
    every ``every`` s, ``block`` or drop late frames, the playback ``rate`` (``None``:
    as fast as it runs), the cloud ``voxel`` (m), the scene ``memory`` voxel (m) with
    its ``memory_box`` and the transform lookup tolerance ``tf_tolerance`` (s)."""

    #: JointState topic.
    joints: str = cli(
        typer.Option(
            "/joint_states",
            "--joints",
            help="sensor_msgs/JointState topic (matched by joint name).",
        )
    )
    #: Cloud or depth-image topics.
    clouds: list[str] = cli(
        typer.Option(
            ...,
            "--clouds",
            help="Cloud topic: sensor_msgs/PointCloud2 or a depth sensor_msgs/Image (16UC1, "
            "32FC1); repeat for several.",
        )
    )
    #: IMAGE_TOPIC=INFO_TOPIC pairs.
    camera_info: list[str] = cli(
        typer.Option(
            [],
            "--camera-info",
            help="IMAGE_TOPIC=INFO_TOPIC: the CameraInfo of a depth topic (default: its sibling "
            "camera_info topic).",
        )
    )
    #: Watch margin (m).
    margin: float = cli(
        typer.Option(
            0.05, "--margin", min=0.0, help="Frames closer than this (m) are reported as near."
        )
    )
    #: World frame.
    frame: str = cli(
        typer.Option(
            "world", "--frame", help="The fixed frame: the robot's base pose is given in it."
        )
    )
    #: Links watched; empty: all with a cloud.
    links: list[str] = cli(
        typer.Option(
            [], "--link", help="Watch only this link (repeat; default: every link with geometry)."
        )
    )
    #: Seconds between replayed frames.
    every: float = cli(
        typer.Option(
            0.0,
            "--every",
            min=0.0,
            help="Least recording time between two frames (s; 0: each joint state).",
        )
    )
    #: Wait for late frames instead of dropping them.
    block: bool = cli(
        typer.Option(
            True,
            "--block/--no-block",
            help="Hand clouds over blocking, so each frame uses the newest cloud received "
            "(the default; the same on any machine), or not, as a live robot: each frame "
            "uses the newest cloud already indexed (pair with --rate).",
        )
    )
    #: Playback rate; ``None``: as fast as it runs.
    rate: float | None = cli(
        typer.Option(
            None,
            "--rate",
            min=0.001,
            help="Pace the replay at this multiple of the recording's speed (1: as recorded; "
            "default: as fast as possible).",
        )
    )
    #: Cloud voxel (m); ``None``: none.
    voxel: float | None = cli(
        typer.Option(
            None,
            "--voxel",
            min=0.0,
            help="Thin each cloud to one point per voxel of this edge (m).",
        )
    )
    #: Scene memory voxel (m); ``None``: no memory.
    memory: float | None = cli(
        typer.Option(
            None,
            "--memory",
            min=0.001,
            help="Fuse the depth-image topics into one scene memory of this voxel edge (m): "
            "the object 'memory' (occupied and shadow voxels; unseen is never free). Needs "
            "--memory-box.",
        )
    )
    #: Memory box x0,y0,z0,x1,y1,z1 (m); ``None``: none.
    memory_box: str | None = cli(
        typer.Option(
            None, "--memory-box", help="x0,y0,z0,x1,y1,z1: the memory's box in --frame (m)."
        )
    )
    #: Transform lookup tolerance (s).
    tf_tolerance: float = cli(
        typer.Option(
            0.0,
            "--tf-tolerance",
            min=0.0,
            help="Use a TF edge's first/last transform up to this long (s) beyond its stamps.",
        )
    )


@dataclass(frozen=True)
class ReplayOutput:
    """Where the results go: the ``out`` folder, the results bag (``results_bag``,
    ``none``: none), JSON on stdout (``json_out``) and the browser viewer afterwards
    (``view``, on ``port``)."""

    #: Output folder.
    out: Path = cli(typer.Option(Path("replay"), "--out", help="Folder for the results."))
    #: Results bag path, auto or none.
    results_bag: str = cli(
        typer.Option(
            "auto",
            "--results-bag",
            help="The results as a bag in --out: .bag ROS 1, .mcap MCAP, else ROS 2 sqlite3; "
            "'auto': results.bag for a ROS 1 recording, else results.mcap; 'none': none.",
        )
    )
    #: Print the summary as JSON.
    json_out: bool = cli(typer.Option(False, "--json", help="Print the summary as JSON."))
    #: Play the replay back in the browser viewer.
    view: bool = cli(
        typer.Option(
            False,
            "--view",
            help="Then play the replay back in the browser viewer (robot, clouds, closest-point "
            "lines; with --memory its occupied, shadow and free voxels) until Ctrl-C.",
        )
    )
    #: The viewer's port.
    port: int = cli(
        typer.Option(
            8080,
            "--port",
            min=0,
            max=65535,
            help="With --view: the viewer's port (or the next free).",
        )
    )


@typed_command(
    order=(
        "bag",
        "robot",
        "scenario",
        "scenario_robot",
        "tip",
        "package_dir",
        "lenient",
        "joints",
        "clouds",
        "camera_info",
        "margin",
        "frame",
        "links",
        "every",
        "block",
        "rate",
        "voxel",
        "points",
        "memory",
        "memory_box",
        "tf_tolerance",
        "out",
        "results_bag",
        "json_out",
        "view",
        "port",
    )
)
def replay(
    source: ReplaySource, robot_file: RobotFileOptions, topics: ReplayTopics,
    output: ReplayOutput,
) -> None:  # fmt: skip
    """Replay a recorded cell: per frame the smallest distance of every watched pair
    (distances.csv, near.csv, summary.json, report.html, a results bag)."""
    from reachwise.errors import InputError
    from reachwise.io.robot_clouds import link_clouds
    from reachwise.io.ros.replay import replay_recording
    from reachwise.report.replay import write_replay_outputs

    spec = _spec(topics)
    robot, scenario, bag = source.robot, source.scenario, source.bag
    out, view = output.out, output.view
    if robot is not None and scenario is not None:
        raise InputError("reachwise replay", "--scenario", "give --robot or --scenario, not both")
    if scenario is not None:
        from reachwise.sim.bag_recorder import scenario_robot as robot_of_scenario

        model, carried = robot_of_scenario(scenario, source.scenario_robot)
    elif robot is not None:
        model = robot_file.load(robot)
        carried = link_clouds(model, source.points)
    else:
        raise InputError("reachwise replay", "--robot", "give --robot or --scenario")
    console = Console(stderr=True)
    console.print(f"replaying {bag} with {model.name} …")
    kept, kept_memory = None, None
    if view:
        from reachwise.viz.replay_view import ReplayClouds, ReplayMemory

        kept = ReplayClouds()
        kept_memory = ReplayMemory() if spec.memory is not None else None
    result = replay_recording(
        bag, model, spec, link_clouds=carried, on_cloud=kept, on_memory=kept_memory
    )
    inputs = {
        "joints": topics.joints,
        "clouds": list(topics.clouds),
        "robot": robot,
        "scenario": scenario,
        "tip": robot_file.tip,
    }
    summary = write_replay_outputs(
        result,
        out,
        inputs,
        results_bag=None if output.results_bag == "none" else output.results_bag,
    )
    if output.json_out:
        typer.echo(json.dumps(summary, indent=2))
    else:
        console.print(
            f"{summary['frames']} frames, smallest distance "
            f"{summary['min_distance'] if summary['min_distance'] is not None else '–'} m, "
            f"{summary['near_frames']} frames closer than {topics.margin:g} m; results in {out}/"
        )
    if view and kept is not None:
        _view(result, model, carried, (kept, kept_memory), output.port, console)


def _spec(topics: ReplayTopics) -> ReplaySpec:
    """The replay's :class:`~reachwise.io.ros.replay.ReplaySpec` from the options
    (``--camera-info`` pairs and ``--memory-box`` parsed)."""
    from reachwise.distance.scene_memory import MemoryConfig
    from reachwise.errors import InputError
    from reachwise.io.ros.replay import ReplaySpec

    infos = {}
    for item in topics.camera_info:
        image, sep, info = item.partition("=")
        if not sep or not image or not info:
            raise InputError("--camera-info", item, "expected IMAGE_TOPIC=INFO_TOPIC")
        infos[image] = info
    box = None
    memory_box = topics.memory_box
    if memory_box is not None:
        try:
            c = [float(v) for v in memory_box.split(",")]
        except ValueError:
            c = []
        if len(c) != 6:
            raise InputError("--memory-box", memory_box, "expected six numbers x0,y0,z0,x1,y1,z1")
        box = ((c[0], c[1], c[2]), (c[3], c[4], c[5]))
    return ReplaySpec(
        joints=topics.joints,
        clouds=tuple(topics.clouds),
        margin=topics.margin,
        frame=topics.frame,
        camera_info=infos,
        links=tuple(topics.links) or None,
        every=topics.every,
        block=topics.block,
        rate=topics.rate,
        voxel=topics.voxel,
        tf_tolerance=topics.tf_tolerance,
        memory=None if topics.memory is None else MemoryConfig(voxel=topics.memory),
        memory_box=box,
    )


def _view(
    result: ReplayResult,
    robot: Robot,
    link_clouds: Mapping[str, PointCloud],
    kept: tuple[ReplayClouds, ReplayMemory | None],
    port: int,
    console: Console,
) -> None:
    """Play ``result`` back in the viewer until Ctrl-C, with the clouds and the scene
    memory (its voxels; ``None``: no memory) ``kept`` while replaying."""
    from reachwise.viz.replay_view import ReplayPlayback
    from reachwise.viz.viewer import Viewer

    viewer = Viewer(port=port)
    try:
        ReplayPlayback(viewer, result, robot, link_clouds, kept[0], memory=kept[1])
    except BaseException:
        viewer.stop()
        raise
    console.print(f"viewer at {viewer.url} (Ctrl-C to stop)")
    viewer.wait()
