"""What ``reachwise view PATH`` can show, found from PATH.

- a built-in robot name or a robot file (``.yaml`` with ``joints``, ``.urdf``): the
  robot with joint sliders;
- a built-in scenario name or a scenario file (``.yaml`` with ``robots``): the scene
  at its start;
- a simulation log folder (``log.npz`` + ``summary.json``, written by
  ``reachwise simulate --out DIR`` into ``DIR/avoidance`` and ``DIR/baseline``): its
  playback; the scene is rebuilt from the scenario the log names (a built-in one, a
  ``scenario.yaml`` next to the log or one folder up, or ``scenario=``);
- a synthesis output folder (``design.yaml`` + ``points.csv``): the configuration at
  each task point;
- a topology report folder (``ranking.json`` + ``designs/``): each ranked design with
  the task's points;
- any folder holding such results (``reachwise-demo/``): all of them, by relative
  path, for the viewer's "Result" dropdown.

:func:`find_results` returns ``{label: show}`` where ``show(viewer)`` loads the result
and fills the viewer; nothing is loaded before it is shown.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from reachwise.errors import InputError, UnknownName

if TYPE_CHECKING:
    from reachwise.viz.canvas import Canvas

__all__ = ["find_results", "result_kind"]

Show = Callable[["Canvas"], None]
MAX_DEPTH = 3


def result_kind(folder: Path) -> str | None:
    """``"simulation"``, ``"synthesis"``, ``"topology"`` or ``None``."""
    if (folder / "log.npz").is_file() and (folder / "summary.json").is_file():
        return "simulation"
    if (folder / "design.yaml").is_file() and (folder / "points.csv").is_file():
        return "synthesis"
    if (folder / "ranking.json").is_file() and (folder / "designs").is_dir():
        return "topology"
    return None


def find_results(path: str | Path, scenario: str | Path | None = None) -> dict[str, Show]:
    """Everything ``path`` holds that the viewer can show (see the module doc)."""
    from reachwise.io.robot_file import builtin_robots
    from reachwise.sim.scenarios import builtin_scenarios

    s = str(path)
    if s in builtin_robots():
        return {s: _robot(s)}
    if s in builtin_scenarios():
        return {s: _scenario(s)}
    p = Path(s)
    if p.is_file():
        return {p.name: _file(p)}
    if p.is_dir():
        found = _walk(p, "", 0, scenario)
        if not found:
            raise InputError(
                str(p),
                "",
                "no result found here: expected a simulation log (log.npz), a synthesis "
                "(design.yaml + points.csv), a topology report (ranking.json) or folders "
                "of them",
            )
        return found
    raise UnknownName(
        s, "file, folder, built-in robot or scenario", s, builtin_robots() + builtin_scenarios()
    )


def _walk(folder: Path, prefix: str, depth: int, scenario: str | Path | None) -> dict[str, Show]:
    label = prefix or folder.name
    kind = result_kind(folder)
    if kind == "simulation":
        return {label: _simulation(folder, scenario)}
    if kind == "synthesis":
        return {label: _synthesis(folder)}
    if kind == "topology":
        return _topology(folder, label)
    out: dict[str, Show] = {}
    if depth >= MAX_DEPTH:
        return out
    for sub in sorted(q for q in folder.iterdir() if q.is_dir() and not q.name.startswith(".")):
        out.update(_walk(sub, f"{prefix}/{sub.name}" if prefix else sub.name, depth + 1, scenario))
    return out


def _file(p: Path) -> Show:
    if p.suffix.lower() == ".urdf":
        return _robot(str(p))
    if p.suffix.lower() not in (".yaml", ".yml"):
        raise InputError(str(p), "", "expected a robot (.yaml, .urdf) or scenario (.yaml) file")
    try:
        data = yaml.safe_load(p.read_text())
    except yaml.YAMLError as exc:
        raise InputError(str(p), "", f"not valid YAML: {exc}") from None
    if isinstance(data, dict) and "robots" in data:
        return _scenario(str(p))
    if isinstance(data, dict) and "joints" in data:
        return _robot(str(p))
    raise InputError(str(p), "", "neither a robot file (joints:) nor a scenario (robots:)")


def _robot(name: str, task: Any = None) -> Show:
    def show(v: Canvas) -> None:
        from reachwise.io.robot_file import load_robot
        from reachwise.viz.modes import show_robot

        show_robot(v, load_robot(name), task=task)

    return show


def _scenario(name: str) -> Show:
    def show(v: Canvas) -> None:
        from reachwise.viz.modes import show_scenario

        show_scenario(v, name)

    return show


def _synthesis(folder: Path) -> Show:
    def show(v: Canvas) -> None:
        from reachwise.results.synthesis_out import load_synthesis
        from reachwise.viz.modes import show_synthesis

        show_synthesis(v, load_synthesis(folder))

    return show


def scenario_of_log(folder: Path, name: str, scenario: str | Path | None = None) -> str | Path:
    """The scenario to rebuild a log's scene from: ``scenario`` if given, the built-in
    one the log names, or ``scenario.yaml`` next to the log or one folder up."""
    from reachwise.sim.scenarios import builtin_scenarios

    if scenario is not None:
        return scenario
    if name in builtin_scenarios():
        return name
    for cand in (folder / "scenario.yaml", folder.parent / "scenario.yaml"):
        if cand.is_file():
            return cand
    raise InputError(
        str(folder),
        "scenario",
        f"the log's scenario {name!r} is not built-in and no scenario.yaml is next to it; "
        "pass --scenario FILE",
    )


def _simulation(folder: Path, scenario: str | Path | None) -> Show:
    cache: dict[str, Any] = {}

    def show(v: Canvas) -> None:
        from reachwise.sim.log import load_log
        from reachwise.sim.world import build_world
        from reachwise.viz.playback import Playback

        if "log" not in cache:
            meta = json.loads((folder / "summary.json").read_text())
            sc = scenario_of_log(folder, str(meta.get("scenario", "")), scenario)
            log = load_log(folder, sc)
            cache["log"], cache["world"] = log, build_world(sc, log.avoidance)
        Playback(v, cache["log"], cache["world"])

    return show


def _topology(folder: Path, label: str) -> dict[str, Show]:
    """One entry per ranked design, shown with the task's points (no status)."""
    try:
        data = json.loads((folder / "ranking.json").read_text())
    except ValueError as exc:
        raise InputError(str(folder / "ranking.json"), "", f"not JSON: {exc}") from None
    designs = sorted((folder / "designs").glob("*.yaml"))
    task_name = data.get("task")  # the final ranking is on the whole task

    def task() -> Any:
        from reachwise.io.task_file import builtin_tasks, load_task

        if not isinstance(task_name, str) or task_name not in builtin_tasks():
            return None
        return load_task(task_name)

    out: dict[str, Show] = {}
    for d in designs:

        def show(v: Canvas, d: Path = d) -> None:
            _robot(str(d), task())(v)

        out[f"{label}/{d.stem}"] = show
    return out
