"""The browser viewer: what it draws (pure parts), every mode on the server side, and
the must-show test driving Debian's headless chromium on a simulation log."""

from __future__ import annotations

import io
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import reachwise
from reachwise.distance.scene import Scene
from reachwise.errors import InputError
from reachwise.sim.log import load_log
from reachwise.sim.world import build_world
from reachwise.viz.nodes import WATCHED_RGB
from reachwise.viz.scene_data import (
    STATUS_RGB,
    joint_ranges,
    pair_segments,
    skeleton_segments,
    status_colours,
    wxyz_position,
)
from reachwise.viz.viewer import Viewer, serve_results
from tests.conftest import random_chain, sigint_default

TIMEOUT = 30.0


def wait_for(cond: Callable[[], bool], timeout: float = TIMEOUT, what: str = "") -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            pytest.fail(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.05)


def port_open(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.settimeout(1.0)
        return s.connect_ex(("127.0.0.1", port)) == 0


def our_threads() -> list[str]:
    """The viewer's own threads (playback, live run) still alive."""
    import threading

    viewers = ("reachwise-playback", "reachwise-live")
    return [t.name for t in threading.enumerate() if t.name in viewers]


def link_position(viewer: Viewer, robot: str, link: str) -> np.ndarray:
    return np.array(viewer.nodes[f"/robots/{robot}/{link}"].position, dtype=float)  # a copy


def assert_robot_at(viewer: Viewer, name: str, q: np.ndarray) -> None:
    """Every link frame of robot ``name`` in the scene sits at its FK pose for ``q``
    (viser drops pose updates within ``np.allclose`` of the last: 1e-5 relative)."""
    view = viewer.robots[name]
    F = view.robot.fk_all(q)
    for k, link in view.links:
        h = viewer.nodes[f"/robots/{name}/{link}"]
        np.testing.assert_allclose(h.position, F[k, :3, 3], atol=1e-4)
        R = Rotation.from_quat(np.roll(np.asarray(h.wxyz), -1)).as_matrix()
        np.testing.assert_allclose(R, F[k, :3, :3], atol=1e-4)


@pytest.fixture(scope="module")
def sim_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short P-V run with and without avoidance, as `reachwise simulate --out` writes."""
    out = tmp_path_factory.mktemp("sim")
    reachwise.simulate("p5-crane-obstacle", duration=3.0).save(out / "avoidance")
    reachwise.simulate("p5-crane-obstacle", avoidance=False, duration=3.0).save(out / "baseline")
    return out


# --------------------------------------------------------------------------- pure parts


@pytest.mark.parametrize("classic", [False, True])
def test_skeleton_joins_the_frame_origins(rng: np.random.Generator, classic: bool) -> None:
    """Segments chain from the base to the tool; each joint's segment is as long as its
    DH offsets hypot(a, d) in either convention (d includes q of a prismatic joint)."""
    robot = random_chain(rng, 7, classic)
    q = rng.uniform(robot.lower, robot.upper)
    seg = skeleton_segments(robot, q)
    assert seg.shape == (len(robot.joints) + 1, 2, 3)
    np.testing.assert_allclose(seg[0, 0], robot.base[:3, 3], atol=1e-12)
    np.testing.assert_allclose(seg[-1, 1], robot.fk(q)[:3, 3], atol=1e-12)
    np.testing.assert_allclose(seg[1:, 0], seg[:-1, 1], atol=1e-12)
    qi = iter(q)
    for k, j in enumerate(robot.joints):
        d = j.d + (next(qi) if j.type == "prismatic" else 0.0)
        if j.type == "revolute":
            next(qi)
        assert np.linalg.norm(seg[k, 1] - seg[k, 0]) == pytest.approx(np.hypot(j.a, d), abs=1e-9)
    assert np.linalg.norm(seg[-1, 1] - seg[-1, 0]) == pytest.approx(
        np.linalg.norm(robot.tool[:3, 3]), abs=1e-9
    )


def test_status_colours_are_those_of_the_figures() -> None:
    from matplotlib.colors import to_rgb

    from reachwise.report.plots import STATUS_COLOURS

    for status, name in STATUS_COLOURS.items():
        expect = np.round(np.array(to_rgb(name)) * 255)
        np.testing.assert_array_equal(status_colours([status])[0], expect)
    assert STATUS_RGB["reached"] == STATUS_RGB["full"]
    assert STATUS_RGB["unreached"] == STATUS_RGB["neither"]
    assert len({STATUS_RGB[s] for s in ("full", "position", "orientation", "neither")}) == 4
    with pytest.raises(InputError, match=r"\[1\].*'done'"):
        status_colours(["full", "done"])


def test_wxyz_position_round_trips(rng: np.random.Generator) -> None:
    R = Rotation.random(random_state=1).as_matrix()
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, rng.normal(size=3)
    wxyz, pos = wxyz_position(T)
    np.testing.assert_allclose(Rotation.from_quat(np.roll(wxyz, -1)).as_matrix(), R, atol=1e-12)
    np.testing.assert_array_equal(pos, T[:3, 3])


def test_pair_segments_are_the_closest_points(rng: np.random.Generator) -> None:
    scene = Scene()
    a = rng.normal(size=(200, 3))
    b = rng.normal(size=(150, 3)) + np.array([5.0, 0.0, 0.0])
    far = rng.normal(size=(100, 3)) + np.array([50.0, 0.0, 0.0])
    scene.add_object("a", a)
    scene.add_object("b", b)
    scene.add_object("far", far)
    scene.watch("a", "b", 10.0)
    scene.watch("a", "far", 10.0)  # beyond its margin: no line
    seg, dist, idx = pair_segments(scene.query_all())
    assert seg.shape == (1, 2, 3) and list(idx) == [0]
    D = np.linalg.norm(a[:, None] - b[None], axis=2)  # brute force
    i, j = np.unravel_index(np.argmin(D), D.shape)
    np.testing.assert_allclose(seg[0], [a[i], b[j]])
    assert dist[0] == pytest.approx(D.min())


def test_joint_ranges_use_limits_or_a_span_around_q() -> None:
    robot = reachwise.load_robot("sb60")
    r = joint_ranges(robot)
    np.testing.assert_array_equal(r, np.column_stack([robot.lower, robot.upper]))
    free = random_chain(np.random.default_rng(3), 4)
    j = replace(free.joints[1], type="prismatic", limits=(-np.inf, np.inf))
    robot2 = replace(free, joints=(free.joints[0], j, *free.joints[2:]))
    q = np.zeros(robot2.n)
    q[1] = 0.7
    r2 = joint_ranges(robot2, q, span=2.0)
    np.testing.assert_allclose(r2[1], [0.7 - 2.0, 0.7 + 2.0])


# --------------------------------------------------------------------------- modes


def test_robot_sliders_move_the_robot(viewer: Viewer) -> None:
    robot = reachwise.load_robot("sb60")
    viewer.show("sb60")
    assert viewer.mode == "robot"
    assert {f"/robots/sb60/{g}/cloud" for g in robot.geometry} <= set(viewer.nodes)
    sliders = viewer.active
    q = np.clip(np.full(robot.n, 0.3), robot.lower, robot.upper)
    for i, s in enumerate(sliders.sliders):  # what a user's drag does: a value per slider
        s.value = float(q[i] * sliders.factor[i])
    assert_robot_at(viewer, "sb60", q)
    seg = np.asarray(viewer.nodes["/robots/sb60/skeleton"].points)
    np.testing.assert_allclose(seg, skeleton_segments(robot, q), atol=1e-5)


def test_scenario_lines_follow_the_sliders(viewer: Viewer) -> None:
    viewer.show("p5-crane-obstacle")
    assert viewer.mode == "scenario"
    world = build_world("p5-crane-obstacle")  # an independent scene for the truth
    q = np.asarray(world.scenario.spec.robots[0].q0, dtype=float)
    lines = viewer.nodes["/distance/lines"]
    start = np.array(lines.points)
    slider = viewer.active.sliders[0]  # the user swings the crane (joint 1, degrees)
    slider.sliders[0].value = 11.5
    q[0] = np.radians(11.5)
    assert_robot_at(viewer, "crane", q)
    world.scene.set_joints("crane", q)
    seg, dist, _ = pair_segments(world.scene.query_all())
    assert len(seg) == 1 and lines.visible
    np.testing.assert_allclose(lines.points, seg, atol=1e-5)
    assert np.abs(np.asarray(lines.points) - start).max() > 0.05  # the line moved
    # the line is the closest pair: 0.3 m margin < its length, so drawn amber
    assert dist[0] > 0.3 and tuple(np.asarray(lines.colors)[0, 0]) == (245, 170, 0)


def test_synthesis_browser_shows_each_configuration(viewer: Viewer, tmp_path: Path) -> None:
    from reachwise import synthesize
    from reachwise.results.synthesis_out import write_synthesis

    task = reachwise.load_task("tunnel-87").subset(np.arange(0, 87, 20), name="tunnel-87")
    res = synthesize(task, "sb60", runs=1, seed=0)
    folder = write_synthesis(res, tmp_path / "synth")
    viewer.show(folder)
    assert viewer.mode == "synthesis"
    browser = viewer.active
    colours = np.asarray(viewer.nodes["/task/points"].colors)
    np.testing.assert_array_equal(colours, status_colours(res.best.status))
    for k in (3, 1):
        browser.slider.value = k  # the user picks point k
        assert browser.index == k and browser.dropdown.value.startswith(f"{k}: ")
        assert_robot_at(viewer, "design", res.q[k])
        np.testing.assert_allclose(viewer.nodes["/task/selected"].position, task.positions[k])
    browser.dropdown.value = browser.labels[2]
    assert browser.index == 2 and browser.slider.value == 2
    assert_robot_at(viewer, "design", res.q[2])


def test_results_folder_offers_every_result(
    viewer: Viewer, sim_folder: Path, tmp_path: Path
) -> None:
    import shutil

    demo = tmp_path / "reachwise-demo"
    shutil.copytree(sim_folder, demo / "simulate-p5-crane-obstacle")
    (demo / "notes").mkdir()
    viewer.show(demo)
    labels = viewer.results.options
    assert labels == ("simulate-p5-crane-obstacle/avoidance", "simulate-p5-crane-obstacle/baseline")
    assert viewer.mode == "playback" and viewer.active.log.avoidance
    viewer.results.value = labels[1]  # the dropdown switches result
    wait_for(lambda: viewer.active is not None and not viewer.active.log.avoidance, what="switch")
    assert viewer.title == labels[1]
    assert "/robots/crane/link_6/cloud" in viewer.nodes
    with pytest.raises(InputError, match="no result found"):
        viewer.show(demo / "notes")


def test_playback_scrubs_to_the_logged_state(viewer: Viewer, sim_folder: Path) -> None:
    viewer.show(sim_folder / "baseline")
    pb = viewer.active
    log = load_log(sim_folder / "baseline")
    world = build_world("p5-crane-obstacle", avoidance=False)
    for k in (250, 40):
        pb.slider.value = float(log.t[k])
        assert pb.index == k
        assert_robot_at(viewer, "crane", log.q["crane"][k])
        world.scene.set_joints("crane", log.q["crane"][k])
        seg, _, _ = pair_segments(world.scene.query_all())
        np.testing.assert_allclose(viewer.nodes["/distance/lines"].points, seg, atol=1e-5)
    path = np.asarray(viewer.nodes["/paths/crane"].points)
    np.testing.assert_allclose(path[0, 0], log.tool["crane"][0, :3, 3], atol=1e-5)
    np.testing.assert_allclose(path[-1, 1], log.tool["crane"][-1, :3, 3], atol=1e-5)


def test_playback_moves_objects_as_logged(viewer: Viewer, tmp_path: Path) -> None:
    from reachwise.sim.scenarios import scenario_from_dict
    from reachwise.viz.playback import Playback

    data = {
        "name": "moving-box", "duration": 1.0,
        "robots": [{"name": "arm", "robot": "puma560", "q0": [0, -0.5, 0.5, 0, 0.3, 0],
                    "goals": [{"q": [0.4, -0.4, 0.6, 0, 0.2, 0]}]}],
        "objects": [{"name": "box", "box": [0.3, 0.3, 0.3], "pose": {"xyz": [0.8, 0, 0.3]},
                     "motion": {"velocity": [-0.2, 0, 0]}}],
        "watch": [{"robot": "arm", "environment": ["box"], "margin": 0.1}],
    }  # fmt: skip
    sc = scenario_from_dict(data, "moving-box.yaml", tmp_path)
    log = reachwise.simulate(sc)
    pb = Playback(viewer, log, build_world(sc))
    for k in (log.t.size - 1, 10):
        pb.slider.value = float(log.t[k])
        np.testing.assert_allclose(
            viewer.nodes["/env/box"].position, log.object_poses["box"][k][:3, 3], atol=1e-9
        )
        assert_robot_at(viewer, "arm", log.q["arm"][k])


def test_live_run_pushes_ticks_then_replays(viewer: Viewer) -> None:
    from reachwise.viz.live import LiveRun

    run = LiveRun(viewer, "p5-crane-obstacle", duration=0.6, speed=0.0, fps=1e6)
    assert viewer.mode == "live"
    run.start(replay=True)
    assert run.done.wait(TIMEOUT)
    wait_for(lambda: viewer.mode == "playback", what="the replay")
    assert run.error is None and run.log is not None
    assert run.ticks == run.log.t.size and run.pushed == run.ticks  # no rate limit here
    assert viewer.active.log is run.log
    # rate-limited: at most one push per 1/fps of wall time
    v2 = LiveRun(viewer, "p5-crane-obstacle", duration=0.4, speed=1.0, fps=10.0)
    t0 = time.monotonic()
    log = v2.run()
    elapsed = time.monotonic() - t0
    assert log is not None and v2.ticks == log.t.size
    assert 1 <= v2.pushed <= elapsed * 10.0 + 1
    viewer.stop()
    assert not our_threads()


def test_files_and_report_folders_are_recognised(viewer: Viewer, tmp_path: Path) -> None:
    import json

    from reachwise.viz.sources import find_results

    robot = reachwise.load_robot("puma560")
    reachwise.save_robot(robot, tmp_path / "arm.yaml")
    (tmp_path / "scene.yaml").write_text(
        "name: one-arm\nduration: 1\nrobots:\n"
        "  - {name: arm, robot: arm.yaml, q0: [0, -0.5, 0.5, 0, 0.3, 0]}\n"
    )
    topo = tmp_path / "topology"
    (topo / "designs").mkdir(parents=True)
    reachwise.save_robot(robot, topo / "designs" / "01-RRR.yaml")
    (topo / "ranking.json").write_text(json.dumps({"task": "tunnel-87"}))
    for path, mode in ((tmp_path / "arm.yaml", "robot"), (tmp_path / "scene.yaml", "scenario")):
        entries = find_results(path)
        assert list(entries) == [path.name]
        viewer.show(path)
        assert viewer.mode == mode
    assert_robot_at(viewer, "arm", np.array([0, -0.5, 0.5, 0, 0.3, 0]))
    assert list(find_results(tmp_path)) == ["topology/01-RRR"]
    viewer.show(topo)
    assert viewer.mode == "robot"
    assert len(viewer.nodes["/task/points"].points) == len(reachwise.load_task("tunnel-87"))
    (tmp_path / "bad.yaml").write_text("just: text\n")
    with pytest.raises(InputError, match="neither a robot file"):
        find_results(tmp_path / "bad.yaml")


def test_busy_port_moves_to_a_free_one() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        busy = s.getsockname()[1]
        said: list[str] = []
        v = serve_results("panda", port=busy, block=False, echo=said.append)
        try:
            assert v.port != busy and port_open(v.port)
            assert said == [f"viewer at http://127.0.0.1:{v.port} (Ctrl-C to stop)"]
        finally:
            v.stop()
        assert not port_open(v.port)


def test_bad_path_is_an_input_error() -> None:
    unknown = r"unknown file, folder, built-in robot or scenario 'no-such-thing'; valid: .*sb60"
    with pytest.raises(InputError, match=unknown):
        serve_results("no-such-thing", port=0, block=False)


CLI_RUNS = {
    "view": (["view", "p3-self-collision"], "viewer at"),
    "view --live": (["view", "p3-self-collision", "--live", "--duration", "0.3", "--speed", "0"],
                    "runs live"),
    "simulate --view": (["simulate", "p3-self-collision", "--duration", "0.3", "--view"],
                        "avoidance:"),
}  # fmt: skip


@pytest.mark.parametrize("case", list(CLI_RUNS))
def test_cli_serves_until_ctrl_c(case: str) -> None:
    """`reachwise view`, `view --live` and `simulate --view` print the URL, serve the
    page, and Ctrl-C ends them cleanly with the port freed."""
    args, expect = CLI_RUNS[case]
    env = dict(os.environ, PYTHONUNBUFFERED="1", COLUMNS="200")
    proc = subprocess.Popen(
        [sys.executable, "-c", "from reachwise.cli import main; main()", *args, "--port", "0"]
        if args[0] == "view"
        else [sys.executable, "-c", "from reachwise.cli import main; main()", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
        preexec_fn=sigint_default,
    )
    try:
        assert proc.stdout is not None
        seen: list[str] = []
        end = time.monotonic() + 60
        while not any(expect in x for x in seen) and time.monotonic() < end:
            line = proc.stdout.readline()
            if not line and proc.poll() is not None:
                break
            seen.append(line)
        text = "".join(seen)
        assert expect in text, text
        url = next(w for x in seen if "viewer at" in x for w in x.split() if "http" in w)
        url = url.rstrip(":")
        port = int(url.rsplit(":", 1)[1])
        with urllib.request.urlopen(url, timeout=10) as r:
            assert r.status == 200 and b"<html" in r.read().lower()
        time.sleep(0.5)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=30) == 0
        assert not port_open(port)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)


def test_live_session_replays_every_run() -> None:
    from reachwise.viz.live import LiveSession

    session = LiveSession("p3-self-collision", port=0, speed=0.0, echo=None)
    try:
        logs = {}
        for avoid, label in ((True, "avoidance"), (False, "baseline")):
            hook = session.hook(avoid, label)
            assert session.viewer.mode == "live"
            logs[label] = reachwise.simulate("p3-self-collision", avoid, duration=0.2, on_tick=hook)
            run = session.run
            assert run is not None and 1 <= run.pushed <= run.ticks == logs[label].t.size
            run.flush()  # the end of the run: its last tick is shown
            assert_robot_at(session.viewer, "boom", logs[label].q["boom"][-1])
        session.replay(logs, block=False)
        v = session.viewer
        assert v.mode == "playback" and v.results.options == ("avoidance", "baseline")
        assert v.active.log is logs["avoidance"]
    finally:
        session.stop()


# --------------------------------------------------------------------------- must show


def test_browser_plays_a_simulation_log(page: Any, sim_folder: Path, tmp_path: Path) -> None:
    """The must-show test of issue 8: the page connects, the scene holds the robot,
    the clouds and the task points, the playback control moves the robot, and a
    screenshot is not blank."""
    from PIL import Image

    log = load_log(sim_folder / "avoidance")
    viewer = serve_results(sim_folder / "avoidance", port=0, block=False, echo=None)
    port = viewer.port
    try:
        world = build_world("p5-crane-obstacle")
        # the scene: the robot's clouds (as many points as the scene's), the scan, the goals
        for name, obj in world.scene.objects.items():
            node = f"/robots/{name}/cloud" if "/" in name else f"/env/{name}"
            assert len(viewer.nodes[node].points) == len(obj.cloud.points), node
            assert viewer.nodes[node].visible
        goals = viewer.nodes["/task/points"]
        assert len(goals.points) == 2 and goals.visible
        assert_robot_at(viewer, "crane", log.q["crane"][0])

        page.goto(viewer.url, timeout=TIMEOUT * 1000)
        wait_for(lambda: len(viewer.server.get_clients()) == 1, what="the page to connect")
        page.wait_for_selector("canvas", timeout=TIMEOUT * 1000)
        pb = viewer.active
        before = link_position(viewer, "crane", "link_6")
        page.get_by_role("button", name="Play").click(timeout=TIMEOUT * 1000)
        wait_for(lambda: pb.index >= 30, what="playback to advance")
        page.get_by_role("button", name="Pause").click(timeout=TIMEOUT * 1000)
        wait_for(lambda: not pb.playing, what="pause")
        k = pb.index
        assert np.linalg.norm(link_position(viewer, "crane", "link_6") - before) > 1e-3
        assert_robot_at(viewer, "crane", log.q["crane"][k])

        # the software renderer draws when it gets to it: look until the robot's
        # (orange) clouds are on screen, with a timeout rather than a fixed pause
        end = time.monotonic() + TIMEOUT
        while True:
            png = page.screenshot(timeout=TIMEOUT * 1000)
            img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))[:, :900]  # 3-D view
            near = np.abs(img.astype(int) - np.array(WATCHED_RGB)).max(axis=2) < 45
            if near.sum() > 200 or time.monotonic() > end:
                break
            time.sleep(0.2)
        (tmp_path / "viewer.png").write_bytes(png)
        assert img.std() > 10.0
        assert len(np.unique(img.reshape(-1, 3) // 16, axis=0)) > 30
        assert near.sum() > 200, "the robot's (orange) clouds are not on screen"
        assert page.console_errors == []
    finally:
        viewer.stop()
    assert not port_open(port)
    assert not our_threads()
