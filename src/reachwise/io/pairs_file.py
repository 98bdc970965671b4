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
    key: 3f1c…                   # fingerprint of robot, clouds and settings (cache)
    rules:                       # what each rule means
      adjacent: …
      never: …
    watched:                     # pairs to watch, with their distance at home
      - {a: link_0, b: link_5, home_distance: 0.636}
    review:                      # watched pairs already within the margin at home
      - {a: link_5, b: link_7, home_distance: 0.002}
    excluded:                    # every pair not watched, with its rule
      - {a: link_0, b: link_1, rule: adjacent, detail: joined by one joint}
      - {a: link_0, b: link_2, rule: never, detail: never within 0.05 m in 10000 …}
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from reachwise.distance.self_pairs import PairRule, SelfPairs
from reachwise.errors import InputError
from reachwise.io.atomic import atomic_write

__all__ = ["RULES", "load_pairs", "pairs_to_dict", "save_pairs"]

#: The rules, in words, written into every pair file.
RULES = {
    "adjacent": "excluded: joined by one joint, rigidly connected, or no link with shapes "
    "between them (MoveIt's 'adjacent')",
    "never": "excluded: never within the margin in any of the random joint vectors inside the "
    "limits (MoveIt's 'never in collision')",
    "review": "watched, but already within the margin at the home configuration: check "
    "whether the two links touch by design (MoveIt would disable them as 'default')",
    "watched": "came within the margin in some random configuration: watched",
}


def _dist(v: float) -> float | None:
    return None if not math.isfinite(v) else round(float(v), 6)


def pairs_to_dict(pairs: SelfPairs, *, source: str = "", key: str = "") -> dict[str, Any]:
    """The YAML mapping of ``pairs`` (see the module docstring)."""
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
            {"a": p.a, "b": p.b, "home_distance": _dist(p.home_distance)}
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
    """Write ``pairs`` as YAML to ``path`` (written whole, then renamed into place)."""
    data = pairs_to_dict(pairs, source=source, key=key)
    head = "# reachwise self-collision pairs (MoveIt Setup Assistant method, exact distances)\n"
    return atomic_write(path, head + yaml.safe_dump(data, sort_keys=False, width=100))


def load_pairs(path: str | os.PathLike[str]) -> tuple[SelfPairs, str]:
    """The pairs in file ``path`` and the key they were computed with."""
    source = str(path)
    try:
        data = yaml.safe_load(Path(path).read_text())
    except OSError as exc:
        raise InputError(source, "", f"cannot read: {exc.strerror or exc}") from None
    except yaml.YAMLError as exc:
        raise InputError(source, "", f"not valid YAML: {exc}") from None
    if not isinstance(data, dict):
        raise InputError(source, "", "a pair file holds a mapping")
    try:
        review = {(e["a"], e["b"]) for e in data.get("review") or []}
        rules = [
            PairRule(
                str(e["a"]),
                str(e["b"]),
                "watched",
                "",
                math.inf if e.get("home_distance") is None else float(e["home_distance"]),
                (e["a"], e["b"]) in review,
            )
            for e in data.get("watched") or []
        ]
        for e in data.get("excluded") or []:
            if e["rule"] not in ("adjacent", "never"):
                raise InputError(source, "excluded", f"unknown rule {e['rule']!r}")
            rules.append(PairRule(str(e["a"]), str(e["b"]), e["rule"], str(e.get("detail", ""))))
        pairs = SelfPairs(
            str(data["robot"]),
            float(data["margin"]),
            int(data["samples"]),
            int(data["seed"]),
            np.asarray(data["home"], dtype=float),
            tuple(rules),
        )
    except InputError:
        raise
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(source, "", f"not a pair file: {exc}") from None
    return pairs, str(data.get("key", ""))
