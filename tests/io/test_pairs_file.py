"""Pair files read like any input: every field checked, each problem a typed error
naming the file and the field; a cache whose content no longer matches its key is
recomputed, never trusted."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

import reachwise
from reachwise.distance.self_pairs import PairRule, SelfPairs
from reachwise.errors import InputError
from reachwise.io.pairs_file import load_pairs, save_pairs, seal
from reachwise.kinematics.robot import Joint, LinkGeometry, Robot


def _pairs() -> SelfPairs:
    rules = (
        PairRule("a", "c", "watched", "within the margin", 0.2),
        PairRule("a", "d", "watched", "review", 0.01, True),
        PairRule("a", "b", "adjacent", "joined by one joint"),
        PairRule("b", "d", "never", "never within 0.05 m"),
        PairRule("c", "d", "always", "always within 0.05 m: in 97.0 % of 100 …"),
    )
    return SelfPairs("arm", 0.05, 100, 3, np.array([0.0, 0.5, -0.25]), rules)


def test_round_trip_keeps_every_field(tmp_path: Path) -> None:
    p = _pairs()
    path = save_pairs(p, tmp_path / "p.yaml", source="arm.urdf", key="k")
    back, key = load_pairs(path)
    assert key == seal(p, "k") == seal(back, "k")
    assert (back.robot, back.margin, back.samples, back.seed) == ("arm", 0.05, 100, 3)
    np.testing.assert_array_equal(back.home, p.home)
    assert back.pairs == p.pairs
    assert seal(p, "other") != key


def _edited(tmp_path: Path, edit: Any) -> Path:
    path = save_pairs(_pairs(), tmp_path / "p.yaml")
    data = yaml.safe_load(path.read_text())
    edit(data)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _set(key: str, value: Any) -> Any:
    return lambda d: d.__setitem__(key, value)


def _entry(kind: str, i: int, key: str, value: Any) -> Any:
    return lambda d: d[kind][i].__setitem__(key, value)


BAD = {
    "nan margin": (_set("margin", float("nan")), "margin"),
    "infinite margin": (_set("margin", float("inf")), "margin"),
    "negative margin": (_set("margin", -0.05), "margin"),
    "negative samples": (_set("samples", -3), "samples"),
    "boolean samples": (_set("samples", True), "samples"),
    "float seed": (_set("seed", 1.5), "seed"),
    "negative seed": (_set("seed", -1), "seed"),
    "empty robot": (_set("robot", ""), "robot"),
    "numeric robot": (_set("robot", 7), "robot"),
    "boolean home": (_set("home", [0.0, True, 0.0]), "home"),
    "unknown key": (_set("margins", 0.1), "margins"),
    "negative distance": (_entry("watched", 0, "home_distance", -0.1), "home_distance"),
    "unknown rule": (_entry("excluded", 0, "rule", "sometimes"), "rule"),
    "unknown pair key": (_entry("excluded", 0, "why", "x"), "why"),
    "self pair": (_entry("watched", 0, "b", "a"), "paired with itself"),
    "watched and excluded": (_entry("excluded", 0, "b", "c"), "also listed"),
    "twice watched": (_entry("watched", 1, "b", "c"), "also listed"),
    "review not watched": (_entry("review", 0, "b", "b"), "not watched"),
    "missing margin": (lambda d: d.pop("margin"), "margin"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_bad_field_is_an_input_error_naming_the_file(tmp_path: Path, case: str) -> None:
    edit, words = BAD[case]
    path = _edited(tmp_path, edit)
    with pytest.raises(InputError, match=words) as info:
        load_pairs(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize(
    ("text", "words"),
    [
        (b"robot: arm\nmargin: 0.05\n\xff\xfe\n", "line 3.*not UTF-8"),
        (b"[" * 5000 + b"]" * 5000, "nested deeper than 64 levels"),
        (b"robot: [unclosed\n", "not valid YAML"),
        (b"- 1\n- 2\n", "mapping"),
    ],
)
def test_unreadable_text_is_an_input_error(tmp_path: Path, text: bytes, words: str) -> None:
    path = tmp_path / "p.yaml"
    path.write_bytes(text)
    with pytest.raises(InputError, match=words) as info:
        load_pairs(path)
    assert str(path) in str(info.value)


def _sticks() -> Robot:
    joints = tuple(
        Joint("revolute", a=0.3 if i else 0.0, alpha=(np.pi / 2 if i % 2 else 0.0),
              limits=(-2.5, 2.5))
        for i in range(5)
    )  # fmt: skip
    T = np.eye(4)
    T[0, 3] = 0.15
    box = LinkGeometry("box", size=(0.3, 0.04, 0.04), origin=tuple(map(tuple, T)))
    return Robot("sticks", joints, geometry={f"link_{i}": box for i in (1, 2, 4, 5)})


def test_a_cache_edited_to_drop_a_pair_is_detected_and_recomputed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    import reachwise.sim.self_pairs as sp

    r = _sticks()
    clouds = reachwise.link_clouds(r, points=100)
    home = np.zeros(r.n)
    sp._MEMORY.clear()
    first = sp.auto_self_pairs(r, clouds, 0.05, home=home, samples=200, cache_dir=tmp_path)
    assert len(first.watched) >= 2
    file = tmp_path / "self-pairs-sticks.yaml"
    data = yaml.safe_load(file.read_text())
    data["watched"] = data["watched"][1:]  # a watched pair deleted, the key kept
    file.write_text(yaml.safe_dump(data, sort_keys=False))
    sp._MEMORY.clear()
    calls = []
    real = sp.self_collision_pairs

    def counted(*args: Any, **kwargs: Any) -> SelfPairs:
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(sp, "self_collision_pairs", counted)
    with caplog.at_level(logging.WARNING, logger="reachwise.sim"):
        again = sp.auto_self_pairs(r, clouds, 0.05, home=home, samples=200, cache_dir=tmp_path)
    assert calls == [1] and "does not match its key" in caplog.text
    assert again.watched == first.watched
    assert load_pairs(file)[0].watched == first.watched  # the file is whole again
    # an intact cache is trusted: nothing computed
    sp._MEMORY.clear()
    sp.auto_self_pairs(r, clouds, 0.05, home=home, samples=200, cache_dir=tmp_path)
    assert calls == [1]
    # a cache that fails its checks is recomputed too
    file.write_text(file.read_text().replace("margin: 0.05", "margin: .nan"))
    sp._MEMORY.clear()
    with caplog.at_level(logging.WARNING, logger="reachwise.sim"):
        sp.auto_self_pairs(r, clouds, 0.05, home=home, samples=200, cache_dir=tmp_path)
    assert calls == [1, 1] and "not used" in caplog.text
