"""What the collision-server benchmarks share: ``reachwise serve`` as a child process,
a bare ZeroMQ echo as the transport's floor, and the crane scene they measure.

The scene: the ``hiab-xs033`` loader crane with four 1000-point parts (the L-bracket of
``reachwise bench distance``, P-V's 1000 points per part) on its main boom, outer boom,
telescope and grabber, and a 5500-point scan-like environment (floor, box obstacle,
noise, occlusion shadow; P-V §IV) 3.5 m out, watched with a 1 m margin. The crane slews
and luffs along a smooth path (:func:`crane_q`), so pairs come in and out of the margin
and the warm starts work as in a control loop.
"""

from __future__ import annotations

import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from reachwise.kinematics.robot import Robot
from reachwise.runtime.realtime import fifo_refusal
from reachwise.server.client import SceneLike

__all__ = [
    "ECHO_REPLY_BYTES",
    "ECHO_REQUEST_BYTES",
    "ENV_X",
    "LINKS",
    "MARGIN",
    "PRIORITY",
    "RATE_HZ",
    "ROBOT",
    "EchoProcess",
    "ServerProcess",
    "bench_priority",
    "build_scene",
    "crane_q",
    "priority_args",
    "rss_bytes",
]

ROBOT = "hiab-xs033"
LINKS = ("link_2", "link_3", "link_4", "link_6")
MARGIN = 1.0  # m
ENV_X = 3.5  # m, environment offset along world x
RATE_HZ = 100.0  # the thesis's control rate (P-V: 10 ms cycles)


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


#: The SCHED_FIFO priority the server benchmarks run the server, its echo twin and the
#: querying loop at (ros2_control's default), where the OS permits it.
PRIORITY = 50


def bench_priority() -> int | None:
    """:data:`PRIORITY` where this machine permits SCHED_FIFO, else None."""
    return PRIORITY if sys.platform == "linux" and not fifo_refusal(PRIORITY) else None


def priority_args(priority: int | None) -> tuple[str, ...]:
    """``reachwise serve``'s options for ``priority`` (none for None)."""
    return ("--priority", str(priority)) if priority is not None else ()


class ServerProcess:
    """``reachwise serve`` as a child process: loopback ``bind`` (a free
    port by default), a state directory in ``workdir``, its log in
    ``workdir/server.log``. Entering starts it and waits for its endpoint; leaving
    stops it (SIGTERM, then SIGKILL after ``stop_timeout`` s). The server also stops by
    itself after ``max_runtime`` s, so none outlives its user. ``priority``: serve under
    SCHED_FIFO at that priority (``--priority``; :func:`bench_priority`), or None."""

    def __init__(
        self,
        workdir: Path,
        max_runtime: float,
        *,
        bind: str = "tcp://127.0.0.1:*",
        extra: tuple[str, ...] = (),
        stop_timeout: float = 10.0,
        priority: int | None = None,
    ) -> None:
        self.workdir = workdir
        self.priority = priority
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
            *priority_args(priority),
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
ctx = zmq.Context(2)  # the server's two I/O threads
s = ctx.socket(zmq.ROUTER); s.linger = 0
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
    """The bare echo server of :data:`_ECHO` in a child process (at normal priority,
    as the round trip's server runs), and a REQ socket to it."""

    def __init__(self, workdir: Path, max_runtime: float) -> None:
        import zmq

        path = workdir / "echo-endpoint"
        args = [str(path), str(ECHO_REPLY_BYTES), str(max_runtime)]
        self.proc = subprocess.Popen([sys.executable, "-c", _ECHO, *args])
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
