"""A scenario's ``size_limits:`` block: the bounds on sampled points, camera pixels and cloud
files are the documented defaults, and a file can raise or lower each; a value beyond
its bound is an error naming the file, the field and the limit to raise."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from reachwise.errors import InputError
from reachwise.geometry.cloud import MAX_SAMPLED_POINTS, PointCloud
from reachwise.io._builtin import builtin_text
from reachwise.io.cloud_headers import MAX_CLOUD_POINTS
from reachwise.io.clouds import save_cloud
from reachwise.sim.resolve import resolve_scenario
from reachwise.sim.scenarios import MAX_IMAGE_SIDE, LimitsSpec, load_scenario


def _write(tmp_path: Path, name: str, edit: Any) -> Path:
    data = yaml.safe_load(builtin_text("scenarios", name))
    edit(data)
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_the_defaults_are_the_documented_bounds() -> None:
    limits = LimitsSpec()
    assert limits.max_points == MAX_SAMPLED_POINTS == 5_000_000
    assert limits.max_image_side == MAX_IMAGE_SIDE == 8192
    assert limits.max_cloud_points == MAX_CLOUD_POINTS == 50_000_000
    assert load_scenario("panda-person-camera").spec.size_limits == limits


def test_a_camera_wider_than_the_default_is_accepted_when_the_file_raises_it(
    tmp_path: Path,
) -> None:
    def wide(d: dict[str, Any], limit: int | None = None) -> None:
        d["sensors"][0].update(width=10_000)
        if limit is not None:
            d["size_limits"] = {"max_image_side": limit}

    path = _write(tmp_path, "panda-person-camera", wide)
    with pytest.raises(InputError) as info:
        load_scenario(str(path))
    assert info.value.source == str(path) and info.value.field == "sensors[0].width"
    assert "at most 8192 (size_limits.max_image_side), got 10000" in info.value.reason
    path = _write(tmp_path, "panda-person-camera", lambda d: wide(d, 10_000))
    assert load_scenario(str(path)).spec.sensors[0].width == 10_000


def test_a_lowered_bound_refuses_what_the_default_allows(tmp_path: Path) -> None:
    def few(d: dict[str, Any]) -> None:
        d["robots"][0]["points"] = 1000
        d["size_limits"] = {"max_points": 500}

    path = _write(tmp_path, "p3-self-collision", few)
    with pytest.raises(InputError) as info:
        load_scenario(str(path))
    assert info.value.source == str(path)
    assert "at most 500 (size_limits.max_points)" in info.value.reason


def test_the_cloud_file_bound_reaches_the_reader(tmp_path: Path) -> None:
    cloud = save_cloud(PointCloud(np.random.default_rng(0).uniform(-1, 1, (40, 3))),
                       tmp_path / "c.xyz")  # fmt: skip

    def with_file(d: dict[str, Any], limit: int) -> None:
        d["objects"] = [{"name": "cloud", "file": str(cloud)}]
        d["size_limits"] = {"max_cloud_points": limit}

    path = _write(tmp_path, "p3-self-collision", lambda d: with_file(d, 39))
    with pytest.raises(InputError, match="more than the bound 39") as info:
        resolve_scenario(str(path))
    assert info.value.source == str(path) and info.value.field == "objects.cloud"
    assert str(cloud) in info.value.reason
    path = _write(tmp_path, "p3-self-collision", lambda d: with_file(d, 40))
    assert len(resolve_scenario(str(path)).object_clouds["cloud"]) == 40


@pytest.mark.parametrize("bad", [True, 0, -3, 1.5, "many"])
def test_a_limit_is_a_whole_number_above_zero(tmp_path: Path, bad: Any) -> None:
    path = _write(
        tmp_path, "p3-self-collision", lambda d: d.update(size_limits={"max_points": bad})
    )
    with pytest.raises(InputError) as info:
        load_scenario(str(path))
    assert info.value.source == str(path) and info.value.field == "size_limits.max_points"
