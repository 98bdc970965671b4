"""Seeded fuzzing of every file loader: robot, task (YAML and CSV), scenario and
self-collision pair files and PLY, PCD, NPY, XYZ and CSV clouds, each mutated many ways
(bytes flipped, inserted or cut, non-UTF-8 bytes, values swapped for booleans, nulls,
strings, huge numbers, deep nesting, keys deleted). Every case gives either a valid
object or a ReachwiseError whose message names the file — never another exception."""

from __future__ import annotations

import copy
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from reachwise.distance.self_pairs import PairRule, SelfPairs
from reachwise.errors import ReachwiseError
from reachwise.geometry.cloud import PointCloud
from reachwise.io._builtin import builtin_text
from reachwise.io.clouds import load_cloud, save_cloud
from reachwise.io.pairs_file import load_pairs, save_pairs
from reachwise.io.robot_file import load_robot
from reachwise.io.task_file import load_task, save_task
from reachwise.sim.scenarios import load_scenario

SEED = 32
BYTE_CASES = 60
VALUE_CASES = 60
SWAPS: list[Any] = [
    True, False, None, "", "x", -1, 0, 10**30, -(10**30), 1e308, -1e308, ".nan", [], {},
    [[[[[[[[[[[[1]]]]]]]]]]]], "\xff", [True, 0, 0], {"a": 1},
]  # fmt: skip


def _bytes_mutation(data: bytes, rng: np.random.Generator) -> bytes:
    """One random byte-level mutation of ``data``."""
    kind = int(rng.integers(7))
    n = len(data)
    at = int(rng.integers(max(n, 1)))
    if kind == 0:  # truncate
        return data[:at]
    if kind == 1:  # flip a few bytes
        out = bytearray(data)
        for i in rng.integers(0, max(n, 1), size=int(rng.integers(1, 8))):
            if n:
                out[int(i)] = int(rng.integers(256))
        return bytes(out)
    if kind == 2:  # insert random bytes
        return (
            data[:at]
            + rng.integers(0, 256, int(rng.integers(1, 64))).astype(np.uint8).tobytes()
            + data[at:]
        )
    if kind == 3:  # non-UTF-8 bytes
        return data[:at] + b"\xc3\x28\xff\xfe" + data[at:]
    if kind == 4:  # duplicate a chunk
        end = min(n, at + int(rng.integers(1, 200)))
        return data[:end] + data[at:end] + data[end:]
    if kind == 5:  # a run of digits
        return data[:at] + str(int(rng.integers(1, 10**12))).encode() + data[at:]
    depth = int(rng.choice([70, 3000, 100_000]))  # deep nesting
    return data[:at] + b"[" * depth + b"]" * depth + data[at:]


def _paths(value: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every location in a parsed YAML document."""
    out = [prefix] if prefix else []
    if isinstance(value, dict):
        for k, v in value.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            out += _paths(v, (*prefix, i))
    return out


def _value_mutation(doc: Any, rng: np.random.Generator) -> Any:
    """``doc`` with one value swapped (or its key deleted, or nested deeply)."""
    out = copy.deepcopy(doc)
    paths = _paths(out)
    path = paths[int(rng.integers(len(paths)))]
    parent = out
    for key in path[:-1]:
        parent = parent[key]
    kind = int(rng.integers(10))
    if kind == 0 and isinstance(parent, dict):
        del parent[path[-1]]
    elif kind == 1:
        deep: Any = 1
        for _ in range(70):  # beyond the nesting bound (deeper: the byte mutations)
            deep = [deep]
        parent[path[-1]] = deep
    else:
        parent[path[-1]] = SWAPS[int(rng.integers(len(SWAPS)))]
    return out


def _check(load: Callable[[str], Any], path: Path, case: str, failures: list[str]) -> None:
    try:
        load(str(path))
    except ReachwiseError as exc:
        if str(path) not in str(exc):
            failures.append(f"{case}: error does not name the file: {exc}")
    except RecursionError:
        failures.append(f"{case}: RecursionError")
    except Exception as exc:
        failures.append(f"{case}: {type(exc).__name__}: {str(exc)[:200]}")


def _robot_text() -> str:
    return builtin_text("robots", "sb60")


def _task_text(tmp_path: Path, suffix: str) -> bytes:
    task = load_task("tunnel-87").subset(np.arange(0, 87, 11), name="fuzz")
    path = tmp_path / f"base{suffix}"
    save_task(task, path)
    return path.read_bytes()


def _pairs_text(tmp_path: Path) -> bytes:
    rules = (
        PairRule("link_0", "link_3", "watched", "within the margin", 0.2),
        PairRule("link_1", "link_3", "watched", "review", 0.01, True),
        PairRule("link_0", "link_1", "adjacent", "joined by one joint"),
        PairRule("link_1", "link_2", "adjacent", "joined by one joint"),
        PairRule("link_0", "link_2", "never", "never within 0.05 m"),
    )
    pairs = SelfPairs("arm", 0.05, 100, 3, np.array([0.0, 0.5, -0.25]), rules)
    return save_pairs(pairs, tmp_path / "base-pairs.yaml", source="arm.urdf").read_bytes()


TEXT_FILES: dict[str, tuple[str, Callable[[Path], bytes], Callable[[str], Any]]] = {
    "robot": (".yaml", lambda _: _robot_text().encode(), load_robot),
    "task-yaml": (".yaml", lambda p: _task_text(p, ".yaml"), load_task),
    "task-csv": (".csv", lambda p: _task_text(p, ".csv"), load_task),
    "scenario": (".yaml", lambda _: builtin_text("scenarios", "p3-self-collision").encode(),
                 load_scenario),
    "pairs": (".yaml", _pairs_text, load_pairs),
}  # fmt: skip


@pytest.mark.parametrize("kind", list(TEXT_FILES))
def test_text_files_fuzzed(tmp_path: Path, kind: str) -> None:
    suffix, base_of, load = TEXT_FILES[kind]
    base = base_of(tmp_path)
    good = tmp_path / f"good{suffix}"
    good.write_bytes(base)
    load(str(good))  # the unmutated file is valid
    rng = np.random.default_rng([SEED, len(kind)])
    failures: list[str] = []
    for i in range(BYTE_CASES):
        path = tmp_path / f"b{i}{suffix}"
        path.write_bytes(_bytes_mutation(base, rng))
        _check(load, path, f"{kind} bytes #{i}", failures)
    if suffix == ".yaml":
        doc = yaml.safe_load(base)
        for i in range(VALUE_CASES):
            path = tmp_path / f"v{i}{suffix}"
            path.write_text(yaml.safe_dump(_value_mutation(doc, rng)))
            _check(load, path, f"{kind} value #{i}", failures)
    assert not failures, "\n".join(failures)


CLOUDS = [".ply", "ascii.ply", ".pcd", "ascii.pcd", ".npy", ".xyz", ".csv"]


@pytest.mark.parametrize("name", CLOUDS)
def test_cloud_files_fuzzed(tmp_path: Path, name: str) -> None:
    rng = np.random.default_rng([SEED, len(name)])
    cloud = PointCloud(rng.uniform(-2.0, 2.0, (30, 3)))
    good = tmp_path / f"good{name}"
    save_cloud(cloud, good, ascii=name.startswith("ascii"))
    base = good.read_bytes()
    np.testing.assert_allclose(load_cloud(good).points, cloud.points, atol=1e-9)
    failures: list[str] = []
    for i in range(BYTE_CASES * 2):
        path = tmp_path / f"m{i}{name}"
        path.write_bytes(_bytes_mutation(base, rng))
        _check(load_cloud, path, f"{name} #{i}", failures)
    assert not failures, "\n".join(failures)
