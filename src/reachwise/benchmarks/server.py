"""``reachwise bench server``: the collision server against the same scene in process (issue 7).

The thesis's collision server answered the control system every 10 ms cycle (P-V §V:
all pairs in 1.0 ms on average, σ 1.7 ms, on a laptop; P-IV §5: 8 ms). Here the server
runs as a separate process (``reachwise serve``, loopback TCP, a state
directory, as deployed) and this process is its client.

Workload: the ``hiab-xs033`` loader crane with four 1000-point parts (the L-bracket of
``reachwise bench distance``, P-V's 1000 points per part) on its main boom, outer boom,
telescope and grabber, and a 5500-point scan-like environment (floor, box obstacle,
noise, occlusion shadow; P-V §IV) 3.5 m out: four watched pairs with a 1 m margin. The
crane slews and luffs along a smooth path sampled at 100 Hz, so pairs come in and out
of the margin and the warm starts work as in a control loop.

1. **Round trip.** Query by query, interleaved (same machine load at the same moment):
   ``inprocess`` — :meth:`reachwise.distance.Scene.query_all` here; ``remote`` —
   :meth:`reachwise.server.client.SceneClient.query_all` of the same scene on the
   server, after the same joint state. Both scenes see the same joint sequence, and
   every remote answer is compared with the in-process one (must be identical).
   ``network overhead`` = remote median − in-process median. ``zmq_echo`` is a bare
   pyzmq REQ/ROUTER echo of similar message sizes in another child process, timed in
   the same loop: the transport's own floor on this machine; ``protocol_overhead`` is
   the network overhead above it (encoding, checking, Python). ``.paired_median``
   figures are medians of the per-query differences (remote − in-process, and minus
   the echo of the same iteration), which cancel load swings that hit all three at
   once. Also the whole tick (joint state + query): ``tick_inprocess`` and
   ``tick_batched`` (the joint state rides on the query: one round trip).
2. **Soak.** 10 000 ticks at 100 Hz (absolute schedule): each tick sends the joint
   state and queries all pairs (one round trip); a scanner thread with its own
   client replaces the environment with a fresh scan every 100 ticks, concurrently,
   as a scanner process would. Figures: tick time percentiles, lost replies (no
   reply within 100 ms or an invalid result), failed scans, and the server's
   resident memory from the start of the soak (after 200 warm-up ticks) to its end.

Times in microseconds unless the key says otherwise.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from reachwise.benchmarks._harness import BenchReport, Target
from reachwise.benchmarks.distance import environment_points, part_points
from reachwise.distance import Scene
from reachwise.io.robot_file import load_robot
from reachwise.kinematics.robot import Robot
from reachwise.server.client import SceneClient, SceneLike, ServerSceneResult

ROBOT = "hiab-xs033"
LINKS = ("link_2", "link_3", "link_4", "link_6")
MARGIN = 1.0  # m
ENV_X = 3.5  # m, environment offset along world x
RATE_HZ = 100.0
SCAN_EVERY = 100  # ticks
WARMUP_TICKS = 200
LOST_DEADLINE = 0.1  # s: a reply later than this counts as lost


def crane_q(robot: Robot, k: int, rate_hz: float = RATE_HZ) -> NDArray[np.float64]:
    """Joint state at tick ``k``: slewing ±0.4 rad, main boom 0.15–0.45 rad, outer boom
    and telescope moving slowly, the grabber hanging (q5 = q2 + q3, q6 = 0)."""
    t = k / rate_hz
    q = np.zeros(robot.n)
    q[0] = 0.4 * math.sin(0.5 * t)
    q[1] = 0.3 + 0.15 * math.sin(0.31 * t)
    q[2] = -0.9 + 0.2 * math.sin(0.23 * t)
    q[3] = 0.6 + 0.5 * math.sin(0.17 * t)
    q[4] = q[1] + q[2]
    return q


def build_scene(
    scene: SceneLike, robot: Robot, part: NDArray[np.float64], env: NDArray[np.float64]
) -> None:
    """The benchmark scene on ``scene`` (in process or on a server)."""
    scene.add_robot(robot, crane_q(robot, 0))
    for link in LINKS:
        scene.add_object(link, part, robot=robot.name, link=link)
    pose = np.eye(4)
    pose[0, 3] = ENV_X
    scene.add_object("environment", env, pose)
    scene.watch_environment(robot.name, MARGIN)


class ServerProcess:
    """``reachwise serve`` as a child process: loopback ``bind`` (a free
    port by default), a state directory in ``workdir``, its log in
    ``workdir/server.log``. Entering starts it and waits for its endpoint; leaving
    stops it (SIGTERM, then SIGKILL after ``stop_timeout`` s). The server also stops by
    itself after ``max_runtime`` s, so none outlives its user."""

    def __init__(
        self,
        workdir: Path,
        max_runtime: float,
        *,
        bind: str = "tcp://127.0.0.1:*",
        extra: tuple[str, ...] = (),
        stop_timeout: float = 10.0,
    ) -> None:
        self.workdir = workdir
        self.stop_timeout = stop_timeout
        self.endpoint_file = workdir / "endpoint"
        self.cmd = [
            sys.executable,
            "-c",  # not -m: reachwise.cli imports the module before runpy would run it
            "from reachwise.cli.serve import main; main()",
            "--bind",
            bind,
            "--state",
            str(workdir / "state"),
            "--endpoint-file",
            str(self.endpoint_file),
            "--max-runtime",
            str(max_runtime),
            *extra,
        ]
        self.proc: subprocess.Popen[bytes] | None = None
        self.endpoint = ""

    def __enter__(self) -> ServerProcess:
        self.endpoint_file.unlink(missing_ok=True)
        with open(self.workdir / "server.log", "ab") as log:
            self.proc = subprocess.Popen(self.cmd, stdout=log, stderr=log)
        end = time.monotonic() + 60.0
        while not self.endpoint_file.exists():
            if self.proc.poll() is not None or time.monotonic() > end:
                self.kill()
                raise RuntimeError(f"the server did not start: see {self.workdir / 'server.log'}")
            time.sleep(0.02)
        self.endpoint = self.endpoint_file.read_text().strip()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def stop(self) -> int | None:
        """SIGTERM and wait (SIGKILL if it does not stop in time); the exit status."""
        if self.proc is None:
            return None
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=self.stop_timeout)
            except subprocess.TimeoutExpired:
                self.kill()
        return self.proc.returncode

    def kill(self) -> None:
        """SIGKILL, as a crash would, and reap the process."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()

    @property
    def pid(self) -> int:
        if self.proc is None:
            raise RuntimeError("not started")
        return self.proc.pid


#: A bare pyzmq ROUTER echo: the transport's own round trip on this machine, as a floor.
_ECHO = """
import sys, time, zmq
ctx = zmq.Context(); s = ctx.socket(zmq.ROUTER); s.linger = 0
s.bind("tcp://127.0.0.1:*")
open(sys.argv[1], "w").write(s.getsockopt_string(zmq.LAST_ENDPOINT))
reply = b"r" * int(sys.argv[2]); end = time.monotonic() + float(sys.argv[3])
while time.monotonic() < end:
    if s.poll(100):
        f = s.recv_multipart()
        s.send_multipart([*f[:-1], reply])
        if f[-1] == b"stop":
            break
"""
ECHO_REQUEST_BYTES = 100
ECHO_REPLY_BYTES = 600


class EchoProcess:
    """The bare echo server of :data:`_ECHO` in a child process, and a REQ socket to it."""

    def __init__(self, workdir: Path, max_runtime: float) -> None:
        import zmq

        path = workdir / "echo-endpoint"
        self.proc = subprocess.Popen(
            [sys.executable, "-c", _ECHO, str(path), str(ECHO_REPLY_BYTES), str(max_runtime)]
        )
        end = time.monotonic() + 30.0
        while not path.exists() or not path.read_text():
            if self.proc.poll() is not None or time.monotonic() > end:
                self.proc.kill()
                raise RuntimeError("the echo server did not start")
            time.sleep(0.01)
        self.ctx = zmq.Context()
        self.sock = self.ctx.socket(zmq.REQ)
        self.sock.linger = 0
        self.sock.connect(path.read_text())
        self.request = b"q" * ECHO_REQUEST_BYTES

    def round_trip(self) -> None:
        self.sock.send(self.request)
        if not self.sock.poll(5000):
            raise RuntimeError("the echo server stopped answering")
        self.sock.recv()

    def close(self) -> None:
        self.sock.send(b"stop")
        self.sock.poll(1000)
        self.sock.close(linger=0)
        self.ctx.term()
        try:
            self.proc.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def rss_bytes(pid: int) -> float:
    """Resident memory of process ``pid`` (Linux /proc), NaN where unavailable."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    return math.nan


def _same(a: ServerSceneResult, b: object) -> float:
    """Largest difference between a remote and an in-process result (0 when identical,
    inf when they disagree on pairs, indices or margins)."""
    from reachwise.distance.scene import SceneResult

    if not isinstance(b, SceneResult) or not a.valid or len(a.pairs) != len(b.pairs):
        return math.inf
    worst = 0.0
    for pa, pb in zip(a.pairs, b.pairs, strict=True):
        ra, rb = pa.result, pb.result
        if (pa.a, pa.b, pa.margin) != (pb.a, pb.b, pb.margin) or ra.no_risk != rb.no_risk:
            return math.inf
        if ra.no_risk:
            continue
        if (ra.index_a, ra.index_b) != (rb.index_a, rb.index_b):
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
    local = Scene()
    build_scene(local, robot, part, env)
    clock = time.perf_counter_ns
    echo = EchoProcess(workdir, 600.0)
    with (
        SceneClient(endpoint, deadline=1.0) as remote,
        SceneClient(endpoint, deadline=1.0, batch_inputs=True) as batched,
    ):
        build_scene(remote, robot, part, env)
        diff = 0.0
        within = 0
        t_in = np.empty(n)
        t_re = np.empty(n)
        t_echo = np.empty(n)
        warm = 50
        try:
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
                if k >= 0:
                    t_in[k] = (t1 - t0) * 1e-3
                    t_re[k] = (t2 - t1) * 1e-3
                    t_echo[k] = (t3 - t2) * 1e-3
                diff = max(diff, _same(a, b))
                within += sum(not p.result.no_risk for p in b.pairs)
        finally:
            echo.close()
        rep.add_samples("zmq_echo", t_echo)
        rep.add_samples("inprocess", t_in)
        rep.add_samples("remote", t_re)
        rep.metrics["remote_vs_inprocess.max_abs_diff_m"] = diff
        rep.notes.append(
            f"round trip: {n} queries of {len(b.pairs)} pairs, {within / (n + warm):.2f} "
            "pairs within the margin per query on average"
        )
        # whole tick: joint state + query; batched = one round trip
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
        compute = remote.metrics().query_compute
        rep.notes.append(f"server query compute histogram (µs edges 1-2-5 …): {list(compute)}")
    overhead = rep.metrics["remote.median"] - rep.metrics["inprocess.median"]
    rep.metrics["network_overhead.median"] = overhead
    rep.metrics["network_overhead.p99"] = rep.metrics["remote.p99"] - rep.metrics["inprocess.p99"]
    rep.metrics["protocol_overhead.median"] = overhead - rep.metrics["zmq_echo.median"]
    rep.metrics["network_overhead.paired_median"] = float(np.median(t_re - t_in))
    rep.metrics["protocol_overhead.paired_median"] = float(np.median(t_re - t_in - t_echo))
    rep.notes.append(
        "read network_overhead against zmq_echo (a bare pyzmq REQ/ROUTER round trip between "
        "two processes, timed in the same loop): the overhead cannot fall below that floor; "
        "protocol_overhead is what our encoding, checking and dispatch add to it"
    )
    rep.ratio("remote", "inprocess")
    rep.targets["network_overhead_p50_us"] = Target(overhead, 100.0)
    rep.targets["remote_identical_to_inprocess_m"] = Target(diff, 0.0)


def _soak(
    rep: BenchReport,
    server: ServerProcess,
    robot: Robot,
    ticks: int,
    scans: list[NDArray[np.float64]],
) -> None:
    period = 1.0 / RATE_HZ
    scan_due = threading.Event()
    stop = threading.Event()
    scan_times: list[float] = []
    scan_failures: list[str] = []

    def scanner() -> None:
        with SceneClient(server.endpoint, setup_deadline=5.0) as sc:
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

    thread = threading.Thread(target=scanner, name="bench-scanner", daemon=True)
    thread.start()
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
        stop.set()
        scan_due.set()
        thread.join()
        client.close()
    rep.add_samples("soak_tick", times)
    rep.metrics["soak.ticks"] = float(ticks)
    rep.metrics["soak.lost_replies"] = float(lost)
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


def run(quick: bool = False) -> BenchReport:
    rep = BenchReport("server")
    robot = load_robot(ROBOT)
    part = part_points(1000, seed=1)
    env = environment_points(5500, seed=2)
    n_rt = 300 if quick else 3000
    ticks = 1000 if quick else 10_000
    scans = [environment_points(5500, seed=10 + i) for i in range(5)]
    rep.notes.append(
        f"server: separate process on tcp://127.0.0.1 with a state directory; load average "
        f"at start {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs"
    )
    with tempfile.TemporaryDirectory(prefix="reachwise-bench-server-") as tmp:
        soak_s = (WARMUP_TICKS + ticks) / RATE_HZ
        with ServerProcess(Path(tmp), soak_s + 900.0) as server:
            with SceneClient(server.endpoint) as c:
                c.wait_ready(60.0)
            _round_trip(rep, Path(tmp), server.endpoint, robot, part, env, n_rt)
            _soak(rep, server, robot, ticks, scans)
    rep.notes.append(
        f"soak: {ticks} ticks at {RATE_HZ:g} Hz after {WARMUP_TICKS} warm-up ticks, scan "
        f"replaced every {SCAN_EVERY} ticks by a concurrent scanner client; a reply later "
        f"than {LOST_DEADLINE * 1e3:g} ms counts as lost"
    )
    if quick:
        rep.notes.append(
            f"quick mode: {n_rt} round trips and a {ticks}-tick soak instead of 3000 and "
            "10 000 (the issue's soak is 10 000 ticks)"
        )
    return rep
