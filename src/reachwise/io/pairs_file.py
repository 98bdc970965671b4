"""Self-collision pair files: which link pairs of a robot are watched, and why not.

``reachwise robot pairs ROBOT --out pairs.yaml`` writes one; a scenario with
``self: {robot: arm, pairs: auto}`` writes one next to its results. The computation is
:func:`reachwise.distance.self_pairs.self_collision_pairs`; the file::

    robot: panda                 # name of the robot
    source: …/panda.urdf         # its file
    margin: 0.05                 # m: a pair within it counts as close
    samples: 10000               # random joint vectors inside the limits
    seed: 0
    home: [0.0, …]               # the home (start) configuration
    key: 3f1c…                   # fingerprint of robot, clouds, settings and the pairs
    rules:                       # what each rule means
      adjacent: …
      always: …
      never: …
    watched:                     # pairs to watch, with their distance at home
      - {a: link_0, b: link_5, home_distance: 0.636, detail: within the margin in …}
      - {a: link_5, b: link_7, home_distance: 0.024, detail: …, margin: 0.004}  # its own
    review:                      # watched pairs already within the margin at home
      - {a: link_5, b: link_7, home_distance: 0.002}
    excluded:                    # every pair not watched, with its rule
      - {a: link_0, b: link_1, rule: adjacent, detail: joined by one joint}
      - {a: link_0, b: link_2, rule: never, detail: never within 0.05 m in 10000 …}
      - {a: wrist_1_link, b: wrist_3_link, rule: always, detail: always within 0.02 m: …}

Every field is checked when the file is read (:func:`load_pairs`): a string robot
name, a finite margin > 0, integer ``samples`` ≥ 1 and ``seed`` ≥ 0 (a boolean is not a
number), finite ``home`` values, distances ≥ 0, a pair's own finite ``margin``, known
rules, no unknown keys, no link paired with itself, no pair listed twice (watched and
excluded, say), every ``review`` pair also watched; text that is not UTF-8 or nested
too deep is refused. Each problem is an :class:`~reachwise.errors.InputError` naming
the file and the field. ``key`` seals the content (:func:`seal`): a file whose pairs
were edited no longer matches its key, so a cache holding it is recomputed, never
trusted.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from reachwise.distance.self_pairs import PairRule, SelfPairs
from reachwise.errors import InputError
from reachwise.io.atomic import atomic_write
from reachwise.io.text_input import parse_text, read_text
from reachwise.io.validation import input_error

__all__ = ["RULES", "load_pairs", "pairs_to_dict", "save_pairs", "seal"]

#: The rules, in words, written into every pair file.
RULES = {
    "adjacent": "excluded: joined by one joint, rigidly connected, or no link with shapes "
    "between them (MoveIt's 'adjacent')",
    "always": "excluded: within the margin in at least 95 % of the random joint vectors (its "
    "clearance hardly ever exceeds the margin: structurally close; MoveIt's 'always in "
    "collision'), its clouds never within their resolutions, or too coarse to tell (its detail)",
    "never": "excluded: never within the margin in any of the random joint vectors inside the "
    "limits (MoveIt's 'never in collision')",
    "review": "watched, but already within the margin at the home configuration: check "
    "whether the two links touch by design (MoveIt would disable them as 'default')",
    "watched": "came within the margin in some random configuration: watched; a pair with "
    "its own margin is within the common one in at least 95 % of them and its clouds come "
    "within their resolutions: it is beyond its own margin in 95 % (below 0: its clouds are "
    "too coarse to promise the surfaces apart)",
}

_STRICT = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)
_Name = Field(min_length=1)


class _Watched(BaseModel):
    model_config = _STRICT
    a: str = _Name
    b: str = _Name
    home_distance: float | None = Field(default=None, ge=0.0)
    detail: str = ""
    margin: float | None = None


class _Excluded(BaseModel):
    model_config = _STRICT
    a: str = _Name
    b: str = _Name
    rule: Literal["adjacent", "always", "never"]
    detail: str = ""


class _PairsFile(BaseModel):
    """The schema of a pair file (module docstring)."""

    model_config = _STRICT
    robot: str = _Name
    source: str = ""
    margin: float = Field(gt=0.0)
    samples: int = Field(ge=1)
    seed: int = Field(ge=0)
    home: list[float]
    key: str = ""
    rules: dict[str, str] = Field(default_factory=dict)
    watched: list[_Watched] = Field(default_factory=list)
    review: list[_Watched] = Field(default_factory=list)
    excluded: list[_Excluded] = Field(default_factory=list)

    @model_validator(mode="after")
    def _pairs(self) -> _PairsFile:
        seen: dict[frozenset[str], str] = {}
        listed = [(f"watched[{i}]", e.a, e.b) for i, e in enumerate(self.watched)]
        listed += [(f"excluded[{i}]", e.a, e.b) for i, e in enumerate(self.excluded)]
        for where, a, b in listed:
            if a == b:
                raise ValueError(f"{where}: link {a!r} is paired with itself")
            pair = frozenset((a, b))
            if pair in seen:
                raise ValueError(f"{where}: pair ({a}, {b}) is also listed in {seen[pair]}")
            seen[pair] = where
        watched = {frozenset((e.a, e.b)) for e in self.watched}
        for i, e in enumerate(self.review):
            if frozenset((e.a, e.b)) not in watched:
                raise ValueError(f"review[{i}]: pair ({e.a}, {e.b}) is not watched")
        return self


def _dist(v: float) -> float | None:
    return None if not math.isfinite(v) else round(float(v), 6)


def _content(data: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in data.items() if k not in ("key", "source", "rules")}


def seal(pairs: SelfPairs, key: str = "") -> str:
    """A fingerprint (hex SHA-256) of ``key`` (what the pairs were computed from) and of
    every field of ``pairs`` as written to a file: robot, margin, samples, seed, home
    and each pair with its rule, detail and distance."""
    content = _content(pairs_to_dict(pairs))
    h = hashlib.sha256(key.encode())
    h.update(json.dumps(content, sort_keys=True, allow_nan=True).encode())
    return h.hexdigest()


def pairs_to_dict(pairs: SelfPairs, *, source: str = "", key: str = "") -> dict[str, Any]:
    """The YAML mapping of ``pairs`` (see the module docstring); ``key`` as given."""
    return {
        "robot": pairs.robot,
        "source": source,
        "margin": pairs.margin,
        "samples": pairs.samples,
        "seed": pairs.seed,
        "home": [float(v) for v in pairs.home],
        "key": key,
        "rules": dict(RULES),
        "watched": [
            {"a": p.a, "b": p.b, "home_distance": _dist(p.home_distance), "detail": p.detail}
            | ({} if p.margin is None else {"margin": p.margin})
            for p in pairs.pairs
            if p.rule == "watched"
        ],
        "review": [
            {"a": p.a, "b": p.b, "home_distance": _dist(p.home_distance)} for p in pairs.review
        ],
        "excluded": [
            {"a": p.a, "b": p.b, "rule": p.rule, "detail": p.detail} for p in pairs.excluded
        ],
    }


def save_pairs(
    pairs: SelfPairs, path: str | os.PathLike[str], *, source: str = "", key: str = ""
) -> Path:
    """Write ``pairs`` as YAML to ``path`` (written whole, then renamed into place); the
    file's ``key`` is :func:`seal` of ``key`` and the pairs."""
    data = pairs_to_dict(pairs, source=source, key=seal(pairs, key))
    head = "# reachwise self-collision pairs (MoveIt Setup Assistant method, exact distances)\n"
    return atomic_write(path, head + yaml.safe_dump(data, sort_keys=False, width=100))


def load_pairs(path: str | os.PathLike[str]) -> tuple[SelfPairs, str]:
    """The pairs in file ``path`` and its ``key``, every field checked (module
    docstring); a bad file is an :class:`InputError` naming it and the field."""
    source = str(path)
    data = parse_text(read_text(path, source), source, "yaml")
    if not isinstance(data, dict):
        raise InputError(source, "", "a pair file holds a mapping")
    try:
        f = _PairsFile.model_validate(data)
    except ValidationError as exc:
        raise input_error(exc, source) from None
    except RecursionError:
        raise InputError(source, "", "nested too deeply") from None
    review = {frozenset((e.a, e.b)) for e in f.review}
    rules = [
        PairRule(
            e.a,
            e.b,
            "watched",
            e.detail,
            math.inf if e.home_distance is None else e.home_distance,
            frozenset((e.a, e.b)) in review,
            e.margin,
        )
        for e in f.watched
    ]
    rules += [PairRule(e.a, e.b, e.rule, e.detail) for e in f.excluded]
    home = np.asarray(f.home, dtype=float)
    pairs = SelfPairs(f.robot, f.margin, f.samples, f.seed, home, tuple(rules))
    return pairs, f.key
