"""``reachwise bench server``: the collision server against the same scene in process
and keeping up with a depth camera while a 1 kHz loop queries it.

The thesis's collision server answered the control system every 10 ms cycle (P-V §V:
all pairs in 1.0 ms on average, σ 1.7 ms, on a laptop; P-IV §5: 8 ms). Here the server
runs as a separate process (``reachwise serve``, loopback TCP, a state
directory, as deployed) and this process is its client.

Workload: the crane scene of :mod:`reachwise.benchmarks.server_setup` (four 1000-point
parts on the ``hiab-xs033`` crane, a 5500-point scan 3.5 m out, four pairs with a 1 m
margin), moving along a smooth path.

1. **Round trip.** Query by query, interleaved (same machine load at the same moment):
   ``inprocess`` — :meth:`reachwise.distance.Scene.query_all` here; ``remote`` —
   :meth:`reachwise.server.client.SceneClient.query_all` of the same scene on the
   server, after the same joint state (the binary tick path: the client holds the
   layout after its first query). Both scenes see the same joint sequence, and every
   remote answer is compared with the in-process one (must be identical, cloud
   versions and stamps included). ``network overhead`` = remote median − in-process
   median. ``zmq_echo`` is a bare pyzmq REQ/ROUTER echo of similar message sizes in
   another child process, timed in the same loop: the transport's own floor on this
   machine; ``protocol_overhead`` is the network overhead above it (encoding,
   checking, Python). ``.paired_median`` figures are medians of the per-query
   differences (remote − in-process, and minus the echo of the same iteration), which
   cancel load swings that hit all three at once; the target is on the paired one.
   ``remote_pairs`` is reading the remote result's pairs (built lazily), and
   ``protocol_overhead_with_pairs`` counts it in. Also the whole tick (joint state +
   query): ``tick_inprocess`` and ``tick_batched`` (the joint state rides on the
   query: one round trip).
2. **Soak.** 10 000 ticks at 100 Hz (absolute schedule): each tick sends the joint
   state and queries all pairs (one round trip); a scanner thread with its own
   client replaces the environment with a fresh scan every 100 ticks, concurrently,
   as a scanner process would. Figures: tick time percentiles, lost replies (no
   reply within 100 ms or an invalid result), failed scans, and the server's
   resident memory from the start of the soak (after 200 warm-up ticks) to its end.
3. **Streaming** (:mod:`reachwise.benchmarks.server_stream`): a camera process hands
   over 300 000-point clouds at 30 Hz while this process queries at 1 kHz;
   :func:`streaming_figures` runs the round trip and this part alone (the
   ``reachwise bench realtime`` server section).
4. **Stages** (:mod:`reachwise.benchmarks.server_stages`): where the request path's
   microseconds go, stage by stage, for the full msgpack path and the binary tick.

Times in microseconds unless the key says otherwise.
"""

from __future__ import annotations

import math
import os
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from reachwise.benchmarks._harness import BenchReport, Target
from reachwise.benchmarks.distance import environment_points, part_points
from reachwise.benchmarks.server_setup import (
    RATE_HZ,
    ROBOT,
    EchoProcess,
    ServerProcess,
    bench_priority,
    build_scene,
    crane_q,
    rss_bytes,
)
from reachwise.benchmarks.server_stages import stage_costs
from reachwise.benchmarks.server_stream import stream
from reachwise.distance import Scene
from reachwise.io.robot_file import load_robot
from reachwise.kinematics.robot import Robot
from reachwise.server.client import SceneClient, ServerSceneResult

__all__ = ["EchoProcess", "ServerProcess", "run", "streaming_figures"]

SCAN_EVERY = 100  # ticks
WARMUP_TICKS = 200
LOST_DEADLINE = 0.1  # s: a reply later than this counts as lost
#: Protocol overhead target beyond the bare echo (µs, p50).
PROTOCOL_OVERHEAD_LIMIT_US = 30.0
#: Streaming workload: a 640 x 480 depth camera at 30 Hz, a 1 kHz loop.
STREAM_POINTS = 300_000
STREAM_HZ = 30.0
QUERY_HZ = 1000.0


def _same(a: ServerSceneResult, b: object) -> float:
    """Largest difference between a remote and an in-process result (0 when identical,
    inf when they disagree on pairs, indices or margins)."""
    from reachwise.distance.scene import SceneResult

    if not isinstance(b, SceneResult) or not a.valid or len(a.pairs) != len(b.pairs):
        return math.inf
    if dict(a.versions) != dict(b.versions) or dict(a.cloud_stamps) != dict(b.cloud_stamps):
        return math.inf
    worst = 0.0
    for pa, pb in zip(a.pairs, b.pairs, strict=True):
        ra, rb = pa.result, pb.result
        if (pa.a, pa.b, pa.margin) != (pb.a, pb.b, pb.margin) or ra.no_risk != rb.no_risk:
            return math.inf
        if ra.no_risk:
            continue
        if (ra.index_a, ra.index_b) != (rb.index_a, rb.index_b) or pa.versions != pb.versions:
            return math.inf
        for x, y in (
            (ra.point_a, rb.point_a),
            (ra.point_b, rb.point_b),
            (ra.direction, rb.direction),
        ):
            worst = max(worst, float(np.max(np.abs(x - y))))
        worst = max(worst, abs(ra.distance - rb.distance))
    return worst


def _round_trip(
    rep: BenchReport,
    workdir: Path,
    endpoint: str,
    robot: Robot,
    part: NDArray[np.float64],
    env: NDArray[np.float64],
    n: int,
) -> None:
    """The round trip (module docstring, part 1): ``n`` queries of the scene in process,
    on the server at ``endpoint`` and of the bare echo, interleaved; then ``n`` whole
    ticks in process and batched."""
    local = Scene()
    build_scene(local, robot, part, env)
    echo = EchoProcess(workdir, 600.0)
    with (
        SceneClient(endpoint, deadline=1.0) as remote,
        SceneClient(endpoint, deadline=1.0, batch_inputs=True) as batched,
    ):
        build_scene(remote, robot, part, env)
        try:
            t_in, t_re, t_echo, t_pairs, diff = _paired_queries(rep, local, remote, echo, robot, n)
        finally:
            echo.close()
        _whole_ticks(rep, local, batched, robot, n)
        compute = remote.metrics().query_compute
        rep.notes.append(f"server query compute histogram (µs edges 1-2-5 …): {list(compute)}")
    overhead = rep.metrics["remote.median"] - rep.metrics["inprocess.median"]
    rep.metrics["network_overhead.median"] = overhead
    rep.metrics["network_overhead.p99"] = rep.metrics["remote.p99"] - rep.metrics["inprocess.p99"]
    rep.metrics["protocol_overhead.median"] = overhead - rep.metrics["zmq_echo.median"]
    rep.metrics["network_overhead.paired_median"] = float(np.median(t_re - t_in))
    paired = float(np.median(t_re - t_in - t_echo))
    rep.metrics["protocol_overhead.paired_median"] = paired
    rep.metrics["protocol_overhead_with_pairs.paired_median"] = float(
        np.median(t_re + t_pairs - t_in - t_echo)
    )
    rep.notes.append(
        "read network_overhead against zmq_echo (a bare pyzmq REQ/ROUTER round trip between "
        "two processes, timed in the same loop): the overhead cannot fall below that floor; "
        "protocol_overhead is what our encoding, checking and dispatch add to it"
    )
    rep.ratio("remote", "inprocess")
    rep.targets["network_overhead_p50_us"] = Target(overhead, 100.0)
    rep.targets["protocol_overhead_p50_us"] = Target(paired, PROTOCOL_OVERHEAD_LIMIT_US)
    rep.targets["remote_identical_to_inprocess_m"] = Target(diff, 0.0)


def _paired_queries(
    rep: BenchReport,
    local: Scene,
    remote: SceneClient,
    echo: EchoProcess,
    robot: Robot,
    n: int,
) -> tuple[
    NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float
]:
    """``n`` queries (after 50 warm-up ones) in process, on the server and of the echo,
    one after the other in each iteration, after the same joint state: their times (µs:
    in process, remote, echo, reading the remote pairs) and the largest difference
    between the remote and the in-process answers; adds their samples to ``rep``."""
    clock = time.perf_counter_ns
    diff = 0.0
    within = 0
    t_in = np.empty(n)
    t_re = np.empty(n)
    t_pairs = np.empty(n)
    t_echo = np.empty(n)
    warm = 50
    for k in range(-warm, n):
        q = crane_q(robot, k + warm)
        local.set_joints(robot.name, q)
        remote.set_joints(robot.name, q)
        t0 = clock()
        b = local.query_all()
        t1 = clock()
        a = remote.query_all()
        t2 = clock()
        echo.round_trip()
        t3 = clock()
        a.pairs  # noqa: B018 - built on first reading: timed apart
        t4 = clock()
        if k >= 0:
            t_in[k] = (t1 - t0) * 1e-3
            t_re[k] = (t2 - t1) * 1e-3
            t_echo[k] = (t3 - t2) * 1e-3
            t_pairs[k] = (t4 - t3) * 1e-3
        diff = max(diff, _same(a, b))
        within += sum(not p.result.no_risk for p in b.pairs)
    rep.add_samples("zmq_echo", t_echo)
    rep.add_samples("inprocess", t_in)
    rep.add_samples("remote", t_re)
    rep.add_samples("remote_pairs", t_pairs)
    rep.metrics["remote_vs_inprocess.max_abs_diff_m"] = diff
    rep.notes.append(
        f"round trip: {n} queries of {len(b.pairs)} pairs, {within / (n + warm):.2f} "
        "pairs within the margin per query on average"
    )
    return t_in, t_re, t_echo, t_pairs, diff


def _whole_ticks(
    rep: BenchReport, local: Scene, batched: SceneClient, robot: Robot, n: int
) -> None:
    """``n`` whole ticks (joint state + query) in process and on the server with the
    joint state riding on the query (one round trip): ``tick_inprocess`` and
    ``tick_batched`` samples in ``rep``."""
    clock = time.perf_counter_ns
    tick_in = np.empty(n)
    tick_b = np.empty(n)
    for k in range(n):
        q = crane_q(robot, n + k)
        t0 = clock()
        local.set_joints(robot.name, q)
        local.query_all()
        t1 = clock()
        batched.set_joints(robot.name, q)
        r = batched.query_all()
        t2 = clock()
        if not r.valid:
            raise RuntimeError(f"batched tick failed: {r.reason}")
        tick_in[k] = (t1 - t0) * 1e-3
        tick_b[k] = (t2 - t1) * 1e-3
    rep.add_samples("tick_inprocess", tick_in)
    rep.add_samples("tick_batched", tick_b)


class _Scanner:
    """The soak's scanner: a client on its own thread that replaces the environment with
    the next of ``scans`` each time :attr:`due` is set, timing each replacement (µs) and
    counting the failures, until :attr:`stop` is set."""

    def __init__(self, endpoint: str, scans: list[NDArray[np.float64]]) -> None:
        self.endpoint, self.scans = endpoint, scans
        self.due = threading.Event()
        self.stop = threading.Event()
        self.times: list[float] = []
        self.failures: list[str] = []
        self.thread = threading.Thread(target=self._run, name="bench-scanner", daemon=True)

    def _run(self) -> None:
        scan_due, stop, scans = self.due, self.stop, self.scans
        scan_times, scan_failures = self.times, self.failures
        with SceneClient(self.endpoint, setup_deadline=5.0) as sc:
            k = 0
            while not stop.is_set():
                if not scan_due.wait(0.05):
                    continue
                scan_due.clear()
                t0 = time.perf_counter()
                try:
                    sc.replace_cloud("environment", scans[k % len(scans)])
                    scan_times.append((time.perf_counter() - t0) * 1e6)
                except Exception as exc:  # counted and reported, the soak goes on
                    scan_failures.append(f"{type(exc).__name__}: {exc}")
                k += 1

    def close(self) -> None:
        """Stop the thread and wait for it."""
        self.stop.set()
        self.due.set()
        self.thread.join()


def _soak(
    rep: BenchReport,
    server: ServerProcess,
    robot: Robot,
    ticks: int,
    scans: list[NDArray[np.float64]],
) -> None:
    """The soak (module docstring, part 2): ``ticks`` ticks at :data:`RATE_HZ` after
    :data:`WARMUP_TICKS` warm-up ones, a scanner replacing the environment every
    :data:`SCAN_EVERY` ticks; adds its figures to ``rep``."""
    period = 1.0 / RATE_HZ
    scanner = _Scanner(server.endpoint, scans)
    scan_due = scanner.due
    scanner.thread.start()
    total = WARMUP_TICKS + ticks
    times = np.empty(ticks)
    lost = 0
    reasons: list[str] = []
    rss0 = math.nan
    client = SceneClient(server.endpoint, deadline=LOST_DEADLINE, batch_inputs=True)
    try:
        start = time.perf_counter() + 0.05
        for k in range(total):
            target = start + k * period
            delay = target - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            if k == WARMUP_TICKS:
                rss0 = rss_bytes(server.pid)
            if k % SCAN_EVERY == 0 and k > 0:
                scan_due.set()
            t0 = time.perf_counter()
            client.set_joints(robot.name, crane_q(robot, k))
            r = client.query_all()
            dt = (time.perf_counter() - t0) * 1e6
            if k >= WARMUP_TICKS:
                times[k - WARMUP_TICKS] = dt
                if not r.valid:
                    lost += 1
                    if len(reasons) < 3:
                        reasons.append(r.reason)
        time.sleep(0.5)  # let the last scan finish and the live state be written
        rss1 = rss_bytes(server.pid)
    finally:
        scanner.close()
        client.close()
    rep.add_samples("soak_tick", times)
    rep.metrics["soak.ticks"] = float(ticks)
    rep.metrics["soak.lost_replies"] = float(lost)
    _soak_figures(rep, lost, reasons, scanner, (rss0, rss1))


def _soak_figures(
    rep: BenchReport,
    lost: int,
    reasons: list[str],
    scanner: _Scanner,
    rss: tuple[float, float],
) -> None:
    """The soak's scan figures, the server's memory from ``rss`` (bytes, start and end)
    and the soak's targets and notes, added to ``rep``."""
    scan_times, scan_failures = scanner.times, scanner.failures
    rss0, rss1 = rss
    rep.metrics["soak.scans"] = float(len(scan_times))
    rep.metrics["soak.scan_failures"] = float(len(scan_failures))
    if scan_times:
        rep.metrics["soak.replace_scan.median"] = float(np.median(scan_times))
        rep.metrics["soak.replace_scan.max"] = float(np.max(scan_times))
    rep.metrics["soak.server_rss_start_mb"] = rss0 / 2**20
    rep.metrics["soak.server_rss_end_mb"] = rss1 / 2**20
    change = 100.0 * (rss1 - rss0) / rss0
    rep.metrics["soak.server_rss_change_pct"] = change
    rep.targets["soak_tick_p99_9_us"] = Target(rep.metrics["soak_tick.p99_9"], 10_000.0)
    rep.targets["soak_lost_replies"] = Target(float(lost + len(scan_failures)), 0.0)
    rep.targets["soak_server_rss_abs_change_pct"] = Target(abs(change), 5.0)
    if reasons:
        rep.notes.append(f"lost replies, first reasons: {reasons}")
    if scan_failures:
        rep.notes.append(f"failed scans, first: {scan_failures[:3]}")


def _stream_options(quick: bool) -> dict[str, Any]:
    return {
        "points": STREAM_POINTS,
        "stream_hz": STREAM_HZ,
        "query_hz": QUERY_HZ,
        "seconds": 3.0 if quick else 10.0,
    }


def streaming_figures(
    *, quick: bool = False, round_trips: int | None = None, seconds: float | None = None
) -> dict[str, Any]:
    """The streaming server figures in one run, for ``reachwise bench realtime``: a
    server process, the round trip against the bare ZeroMQ echo (``round_trips``
    queries; protocol overhead), then a camera process streaming 300 000-point clouds
    at 30 Hz while this process queries at 1 kHz (``seconds``).

    Returns the benchmark JSON schema's parts (DESIGN.md): ``{"metrics": {...},
    "ratios": {...}, "targets": {name: {"value", "limit", "met"}}, "notes": [...]}``,
    times in µs unless a key says otherwise."""
    rep = BenchReport("server-streaming")
    robot = load_robot(ROBOT)
    n_rt = round_trips if round_trips is not None else (300 if quick else 3000)
    opts = _stream_options(quick)
    if seconds is not None:
        opts["seconds"] = float(seconds)
    _load_note(rep)
    with tempfile.TemporaryDirectory(prefix="reachwise-bench-stream-") as tmp:
        part, env = part_points(1000, seed=1), environment_points(5500, seed=2)
        _round_trip_at_normal_priority(rep, Path(tmp), robot, part, env, n_rt)
        with _scene_server(tmp, "stream", opts["seconds"] + 900.0, robot, part, env) as server:
            stream(rep, server, robot, **opts)
    d = rep.to_dict()
    return {k: d[k] for k in ("metrics", "ratios", "targets", "notes")}


def _sub(tmp: str, name: str) -> Path:
    """A fresh folder ``name`` in ``tmp`` for one server process."""
    path = Path(tmp) / name
    path.mkdir()
    return path


def _round_trip_at_normal_priority(
    rep: BenchReport,
    tmp: Path,
    robot: Robot,
    part: NDArray[np.float64],
    env: NDArray[np.float64],
    n: int,
) -> None:
    """The round trip against the echo (:func:`_round_trip`) on a server of its own at
    normal priority, the echo too. Measured on the 2-core development machine, under
    SCHED_FIFO the bare echo took 60-90 µs longer (206-236 µs median) and both sides
    were descheduled for 20-40 µs at times inside ZeroMQ's send: scatter larger than
    the protocol's own work this figure is about. The soak and the streaming run under
    FIFO (their figures are tails, which FIFO shortens)."""
    with ServerProcess(_sub(str(tmp), "round-trip"), 900.0) as server:
        with SceneClient(server.endpoint) as c:
            c.wait_ready(60.0)
        _round_trip(rep, server.workdir, server.endpoint, robot, part, env, n)


@contextmanager
def _scene_server(
    tmp: str,
    name: str,
    max_runtime: float,
    robot: Robot,
    part: NDArray[np.float64],
    env: NDArray[np.float64],
) -> Iterator[ServerProcess]:
    """A server process of its own in ``tmp/name`` under SCHED_FIFO where permitted
    (:func:`bench_priority`; the soak's and the streaming's), ready, with the benchmark
    scene (:func:`build_scene`)."""
    with ServerProcess(_sub(tmp, name), max_runtime, priority=bench_priority()) as server:
        with SceneClient(server.endpoint) as c:
            c.wait_ready(60.0)
            build_scene(c, robot, part, env)
        yield server


def _load_note(rep: BenchReport) -> None:
    rep.notes.append(
        f"server: separate process on tcp://127.0.0.1 with a state directory; load average "
        f"at start {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs; "
        + (
            f"the round trip against the echo at normal priority (server and echo); the "
            f"soak and streaming server (its request and ZeroMQ I/O threads) and the "
            f"querying loop under SCHED_FIFO {priority}, as real-time processes run"
            if (priority := bench_priority()) is not None
            else "every process at normal priority (SCHED_FIFO not permitted here)"
        )
    )


def run(quick: bool = False) -> BenchReport:
    rep = BenchReport("server")
    robot = load_robot(ROBOT)
    part = part_points(1000, seed=1)
    env = environment_points(5500, seed=2)
    n_rt = 300 if quick else 3000
    ticks = 1000 if quick else 10_000
    scans = [environment_points(5500, seed=10 + i) for i in range(5)]
    opts = _stream_options(quick)
    _load_note(rep)
    with tempfile.TemporaryDirectory(prefix="reachwise-bench-server-") as tmp:
        soak_s = (WARMUP_TICKS + ticks) / RATE_HZ
        _round_trip_at_normal_priority(rep, Path(tmp), robot, part, env, n_rt)
        runtime = soak_s + opts["seconds"] + 900.0
        with _scene_server(tmp, "soak", runtime, robot, part, env) as server:
            _soak(rep, server, robot, ticks, scans)
            stream(rep, server, robot, **opts)
    stage_costs(rep, robot, 500 if quick else 3000)
    rep.notes.append(
        f"soak: {ticks} ticks at {RATE_HZ:g} Hz after {WARMUP_TICKS} warm-up ticks, scan "
        f"replaced every {SCAN_EVERY} ticks by a concurrent scanner client; a reply later "
        f"than {LOST_DEADLINE * 1e3:g} ms counts as lost"
    )
    if quick:
        rep.notes.append(
            f"quick mode: {n_rt} round trips, a {ticks}-tick soak and {opts['seconds']:g} s "
            "of streaming instead of 3000, 10 000 (the issue's soak) and 10 s"
        )
    return rep
