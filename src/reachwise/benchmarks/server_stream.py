"""A depth camera streaming into the collision server while a control loop queries it:
does the server keep up?

One client process stands for the camera: it hands the server a fresh
``points``-point float32 cloud (a 640 x 480 depth frame is 307 200) ``stream_hz``
times a second, each a raw frame sent without a copy (``replace_cloud``, no
``block``). This process stands for the controller: ``query_hz`` times a second
(absolute schedule) it sends its joint state with the query of every pair, one round
trip (``batch_inputs``), and times the call. The server indexes each cloud on its
indexing worker and swaps it in between two queries; the camera's object is watched
against the crane's parts, so the answers run on the clouds as they come.

Figures (µs unless the key says otherwise): the query call's percentiles and maximum,
lost replies (no reply within :data:`LOST_DEADLINE` or an invalid result), the camera
call's percentiles, hand-overs per second, swaps per second seen in the answers
(distinct camera cloud versions / s), answers whose camera version went back (0), and
the age of the camera cloud each answer used (reply arrival − that cloud's stamp: both
on :func:`time.monotonic`, the clock every process on this host shares).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from reachwise.benchmarks._harness import BenchReport, Target
from reachwise.benchmarks.server_setup import MARGIN, ServerProcess, crane_q
from reachwise.io.atomic import atomic_write
from reachwise.kinematics.robot import Robot
from reachwise.runtime.realtime import realtime_settings
from reachwise.server.client import SceneClient

__all__ = [
    "CAMERA",
    "LOST_DEADLINE",
    "LoopFigures",
    "camera_frame",
    "control_loop",
    "paced_calls",
    "stream",
    "with_camera",
]

#: The streamed object's name.
CAMERA = "camera"
#: A reply later than this (s) counts as lost.
LOST_DEADLINE = 0.1
#: Query percentile target (µs) and the hand-over rate the camera keeps (Hz).
QUERY_P99_9_LIMIT_US = 2000.0


def camera_frame(points: int, k: int, seed: int = 5) -> NDArray[np.float32]:
    """Frame ``k`` of the camera: a person-sized box (0.5 x 0.4 x 1.7 m) walking along
    y in front of the crane, its surface sampled with ``points`` noisy points, float32
    as a depth camera delivers them (seeded: frame ``k`` is always the same)."""
    rng = np.random.default_rng(seed * 1_000_003 + k)
    half = np.array([0.25, 0.2, 0.85])
    pts = rng.uniform(-half, half, (points, 3))
    axis = rng.integers(0, 3, points)
    pts[np.arange(points), axis] = np.where(rng.random(points) < 0.5, -1.0, 1.0) * half[axis]
    centre = np.array([2.3, -0.6 + 0.04 * (k % 30), 0.85])
    pts += centre + rng.normal(scale=0.003, size=pts.shape)
    return np.ascontiguousarray(pts, dtype=np.float32)


#: The camera process: hands over frames at its rate until told to stop; writes what it
#: saw as JSON. Arguments: endpoint, workdir, points, rate (Hz), frames to cycle.
_CAMERA = """
import json, sys
from pathlib import Path
from reachwise.benchmarks.server_stream import CAMERA, camera_frame, paced_calls
from reachwise.io.atomic import atomic_write
from reachwise.server.client import SceneClient
ep, work = sys.argv[1], Path(sys.argv[2])
n, rate, count = int(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5])
frames = [camera_frame(n, k) for k in range(count)]
with SceneClient(ep, setup_deadline=5.0) as c:
    c.replace_cloud(CAMERA, frames[0])
    atomic_write(work / "camera-ready", b"1")
    report = paced_calls(work, rate, lambda k: c.replace_cloud(CAMERA, frames[k % count]))
report["versions"] = report.pop("results")
atomic_write(work / "camera.json", json.dumps(report))
"""


def paced_calls(work: Path, rate: float, call: Callable[[int], object]) -> dict[str, Any]:
    """A camera process's schedule: ``call(k)`` for k = 0, 1, … at ``rate`` Hz (absolute
    schedule) until ``work/camera-stop`` appears (or 600 s pass). Returns its report:
    each call's round trip (``calls_us``), what each returned (``results``), the failures
    (``failures``) and the time spent (``span_s``)."""
    calls: list[float] = []
    results: list[object] = []
    failures: list[str] = []
    start = time.perf_counter()
    k = 0
    while not (work / "camera-stop").exists() and time.perf_counter() - start < 600:
        delay = start + k / rate - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
        t0 = time.perf_counter()
        try:
            results.append(call(k))
            calls.append((time.perf_counter() - t0) * 1e6)
        except Exception as exc:  # a failed call is counted and reported, the stream goes on
            failures.append(f"{type(exc).__name__}: {exc}")
        k += 1
    span = time.perf_counter() - start
    return {"calls_us": calls, "results": results, "failures": failures, "span_s": span}


def stream(
    rep: BenchReport,
    server: ServerProcess,
    robot: Robot,
    *,
    points: int,
    stream_hz: float,
    query_hz: float,
    seconds: float,
    frames: int = 6,
) -> None:
    """Register the camera object on ``server`` (whose scene holds ``robot`` and its
    parts), stream into it from a camera process while querying here; add the figures
    to ``rep``."""
    work = server.workdir
    for f in ("camera-ready", "camera-stop", "camera.json"):
        (work / f).unlink(missing_ok=True)
    with SceneClient(server.endpoint) as setup:
        setup.add_object(CAMERA, camera_frame(points, 0), dynamic=False)
        setup.watch_environment(robot.name, MARGIN, [CAMERA])
    # the same loop on the same scene without the camera first: the machine's own tails
    idle = control_loop(server.endpoint, robot, query_hz, seconds, server.priority)
    before = _handling(server.endpoint)
    camera = [str(points), str(stream_hz), str(frames)]
    loop = with_camera(server, robot, _CAMERA, camera, query_hz, seconds)
    after = _handling(server.endpoint)
    cam_report = json.loads((work / "camera.json").read_text())
    settings = {
        "stream.points": float(points),
        "stream.rate_hz": stream_hz,
        "stream.query_hz": query_hz,
        "stream.seconds_s": seconds,
    }
    _stream_figures(rep, idle, loop, (after[0], after[1] - before[1]), cam_report, settings)
    rep.notes.append(
        f"streaming: a camera process hands over {points}-point float32 clouds at "
        f"{stream_hz:g} Hz (raw frames, no copy, no block) while this process sends its "
        f"joint state and queries every pair at {query_hz:g} Hz for {seconds:g} s; the "
        f"camera's object is watched against the crane's parts. stream_cloud_age: reply "
        f"arrival minus the stamp of the camera cloud the answer used (hand-over, "
        f"indexing and swap). idle_query: the same loop just before, camera object "
        f"registered but not streaming (the machine's own tails). "
        f"stream.server_handling_q*_below_us: the server's own time from receipt to reply "
        f"(its histogram's bucket edge) while streaming"
    )
    if loop[2]:
        rep.notes.append(f"streaming: lost replies, first reasons: {loop[2]}")
    if cam_report["failures"]:
        rep.notes.append(f"streaming: failed hand-overs, first: {cam_report['failures'][:3]}")


#: What :func:`control_loop` returns: query times (µs), lost replies, their first
#: reasons, the camera versions seen, the camera cloud's age per answer (µs) and
#: version regressions.
LoopFigures = tuple[NDArray[np.float64], int, list[str], set[int], NDArray[np.float64], int]


def with_camera(
    server: ServerProcess,
    robot: Robot,
    script: str,
    camera: list[str],
    query_hz: float,
    seconds: float,
    wait_s: float = 60.0,
) -> LoopFigures:
    """The control loop while a camera process (the Python source ``script``, e.g.
    :data:`_CAMERA`; its arguments after the endpoint and folder: ``camera``) streams
    into ``server``; the camera is told to stop and awaited (``wait_s`` s, then killed)
    after the loop, its report left in ``camera.json``."""
    work = server.workdir
    args = [server.endpoint, str(work), *camera]
    cam = subprocess.Popen([sys.executable, "-c", script, *args])
    try:
        end = time.monotonic() + 120.0
        while not (work / "camera-ready").exists():
            if cam.poll() is not None or time.monotonic() > end:
                raise RuntimeError("the camera process did not start")
            time.sleep(0.02)
        return control_loop(server.endpoint, robot, query_hz, seconds, server.priority)
    finally:
        atomic_write(work / "camera-stop", b"1")
        try:
            cam.wait(timeout=wait_s)
        except subprocess.TimeoutExpired:
            cam.kill()
            cam.wait()


def _stream_figures(
    rep: BenchReport,
    idle: LoopFigures,
    loop: LoopFigures,
    handling: tuple[NDArray[np.float64], NDArray[np.int64]],
    cam_report: dict[str, Any],
    settings: dict[str, float],
) -> None:
    """The figures of the loop without (``idle``) and with the camera (``loop``), the
    server's handling while streaming (histogram edges and counts), the camera's
    report and the streaming's ``settings`` (``stream.seconds_s`` among them), with
    their targets, added to ``rep``."""
    q_times, lost, _, seen, ages, regressions = loop
    calls = np.asarray(cam_report["calls_us"], dtype=np.float64)
    rep.add_samples("idle_query", idle[0])
    rep.metrics["idle_query.max"] = float(idle[0].max())
    rep.metrics["idle.lost_replies"] = float(idle[1])
    rep.add_samples("stream_query", q_times)
    rep.metrics["stream_query.max"] = float(q_times.max())
    edges, counts = handling
    for q in (0.5, 0.99, 0.999):
        rep.metrics[f"stream.server_handling_q{q:g}_below_us"] = _upper_edge(edges, counts, q)
    rep.metrics["stream.queries"] = float(q_times.size)
    rep.metrics["stream.lost_replies"] = float(lost)
    rep.metrics.update(settings)
    seconds = settings["stream.seconds_s"]
    if calls.size:
        rep.add_samples("stream_handover", calls)
    span = float(cam_report["span_s"])
    rep.metrics["stream.handovers_per_s"] = len(cam_report["versions"]) / span
    rep.metrics["stream.handover_failures"] = float(len(cam_report["failures"]))
    rep.metrics["stream.swaps_per_s"] = (len(seen) - 1) / seconds if seen else 0.0
    rep.metrics["stream.version_regressions"] = float(regressions)
    if ages.size:
        rep.add_samples("stream_cloud_age", ages)
    rep.targets["stream_query_p99_9_us"] = Target(
        rep.metrics["stream_query.p99_9"], QUERY_P99_9_LIMIT_US
    )
    rep.targets["stream_lost_replies"] = Target(float(lost), 0.0)
    rep.targets["stream_version_regressions"] = Target(float(regressions), 0.0)


def _handling(endpoint: str) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The server's histogram of query handling times: bucket edges (µs), counts."""
    with SceneClient(endpoint) as c:
        m = c.metrics()
    return np.asarray(m.edges_us), np.asarray(m.query_handling, dtype=np.int64)


def _upper_edge(edges: NDArray[np.float64], counts: NDArray[np.int64], q: float) -> float:
    """The bucket edge below which a fraction ``q`` of the counts lie (inf: the last)."""
    total = int(counts.sum())
    if total == 0:
        return math.nan
    k = int(np.searchsorted(np.cumsum(counts), q * total))
    return float(edges[k]) if k < edges.size else math.inf


def control_loop(
    endpoint: str, robot: Robot, rate_hz: float, seconds: float, priority: int | None = None
) -> LoopFigures:
    """The controller: query times (µs), lost replies, their first reasons, the camera
    versions seen, the camera cloud's age per answer (µs) and version regressions. It
    runs as a real-time loop does (:func:`realtime_settings`: no full collection of the
    setup's objects; under SCHED_FIFO at ``priority``, given as the server's), its
    client made inside, so that ZeroMQ's I/O thread shares the loop's scheduling."""
    n = int(seconds * rate_hz)
    warm = int(0.2 * rate_hz)
    period = 1.0 / rate_hz
    with (
        realtime_settings(priority=priority),
        SceneClient(endpoint, deadline=LOST_DEADLINE, batch_inputs=True) as client,
    ):
        start = time.perf_counter() + 0.05
        return _ticks(client, robot, start, period, warm, n)


def _ticks(
    client: SceneClient, robot: Robot, start: float, period: float, warm: int, n: int
) -> LoopFigures:
    """The timed ticks of :func:`control_loop`."""
    times = np.empty(n)
    ages = np.empty(n)
    lost = 0
    reasons: list[str] = []
    seen: set[int] = set()
    last_version = -1
    regressions = 0
    row = -1
    rate_hz = 1.0 / period
    for k in range(-warm, n):
        target = start + (k + warm) * period
        delay = target - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
        t0 = time.perf_counter()
        client.set_joints(robot.name, crane_q(robot, k + warm, rate_hz))
        r = client.query_all()
        dt = (time.perf_counter() - t0) * 1e6
        if k < 0:
            continue
        times[k] = dt
        ages[k] = math.nan
        if not r.valid:
            lost += 1
            if len(reasons) < 3:
                reasons.append(r.reason)
            continue
        clouds = r.clouds
        if clouds is None:
            continue
        if row < 0:
            row = list(r.versions).index(CAMERA)
        version = int(clouds[row, 0])
        seen.add(version)
        if version < last_version:
            regressions += 1
        last_version = version
        ages[k] = (r.computed_at - clouds[row, 1]) * 1e6
    return times, lost, reasons, seen, ages[np.isfinite(ages)], regressions
