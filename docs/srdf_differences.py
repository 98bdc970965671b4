"""Write ``docs/guides/srdf-differences.md``: per example-robot-data arm, where
reachwise's automatic self-collision pairs and the arm's MoveIt SRDF differ, and why.

Run from the repository root (needs the ``robots`` extra)::

    python docs/srdf_differences.py            # rewrite the page
    python docs/srdf_differences.py --check    # exit 1 if the page is not what it computes

``tests/docs/test_srdf_differences.py`` checks the page against the SRDF files and
recomputes one arm's section.
"""

from __future__ import annotations

import argparse
import logging
import sys
from dataclasses import dataclass
from pathlib import Path

#: arm -> (URDF and SRDF inside example-robot-data's robots folder, tip link)
ARMS: dict[str, tuple[str, str, str]] = {
    "panda": ("panda_description/urdf/panda.urdf", "panda_description/srdf/panda.srdf",
              "panda_hand"),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "ur_description/srdf/ur5.srdf", "tool0"),
    "xarm7": ("xarm_description/urdf/xarm7.urdf", "xarm_description/srdf/xarm7.srdf",
              "link_eef"),
    "z1": ("z1_description/urdf/z1.urdf", "z1_description/srdf/z1.srdf", "gripperStator"),
    "kinova": ("kinova_description/robots/kinova.urdf", "kinova_description/srdf/kinova.srdf",
               "j2s6s200_end_effector"),
}  # fmt: skip
MARGIN = 0.05
SAMPLES = 10_000
PAGE = Path(__file__).parent / "guides" / "srdf-differences.md"
WHY = {
    "adjacent": "we exclude it as adjacent (one joint joins them, or they are rigidly joined)",
    "never": f"never within {MARGIN:g} m in {SAMPLES} random configurations and a local search",
    "always": f"within {MARGIN:g} m nearly everywhere (always): excluded, as MoveIt's Always",
}

#: What MoveIt's Setup Assistant means by each reason.
SRDF_WHY = {
    "Adjacent": "Adjacent: one joint joins them",
    "Never": "Never: no contact in its random configurations",
    "Always": "Always: in contact in nearly every configuration",
    "Default": "Default: in contact at the default pose",
    "User": "User: disabled by hand",
}


@dataclass(frozen=True)
class Row:
    """One pair where the two disagree: ``ours`` is our rule, ``srdf`` the SRDF's reason
    (``""``: the SRDF leaves the pair checked)."""

    a: str
    b: str
    ours: str
    srdf: str


def robots_dir() -> Path:
    """example-robot-data's ``robots`` folder."""
    from importlib import metadata

    dist = metadata.distribution("example-robot-data")
    return Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))


def compare(arm: str) -> tuple[list[Row], dict[str, int]]:
    """The pairs of ``arm`` where our rules and its SRDF differ, and counts."""
    import reachwise
    from reachwise.distance.self_pairs import self_collision_pairs
    from reachwise.io.srdf import read_srdf

    urdf, srdf_file, tip = ARMS[arm]
    root = robots_dir()
    robot = reachwise.load_robot(root / urdf, tip=tip)
    clouds = reachwise.link_clouds(robot)
    ours = self_collision_pairs(robot, clouds, MARGIN, samples=SAMPLES, seed=0)
    srdf = read_srdf(root / srdf_file)
    reason = {frozenset((p.link1, p.link2)): p.reason for p in srdf.disabled}
    rows = []
    for p in ours.pairs:
        why = reason.get(frozenset((p.a, p.b)), "")
        if (p.rule == "watched") != (why == ""):
            rows.append(Row(p.a, p.b, p.rule, why))
    mentioned = {x for pair in reason for x in pair}
    counts = {
        "links": len(clouds),
        "pairs": len(ours.pairs),
        "agree": len(ours.pairs) - len(rows),
        "srdf_off_chain": sum(1 for pair in reason if not pair <= set(clouds)),
        "unknown_links": len(mentioned - set(robot.body_names) - set(robot.link_names)),
    }
    return rows, counts


def section(arm: str) -> str:
    """The Markdown section of ``arm``."""
    rows, c = compare(arm)
    urdf, srdf_file, tip = ARMS[arm]
    watched_off = [r for r in rows if r.ours == "watched"]
    excluded_on = [r for r in rows if r.ours != "watched"]
    out = [
        f"## {arm}",
        "",
        f"`{urdf}` (tip `{tip}`) against `{srdf_file}`: {c['links']} links with clouds, "
        f"{c['pairs']} pairs; the two agree on {c['agree']}. The SRDF's pairs naming a "
        f"link off the loaded chain: {c['srdf_off_chain']}.",
        "",
        f"- **We watch, MoveIt disables** ({len(watched_off)}): they come within "
        f"{MARGIN:g} m of each other but never touch in MoveIt's sampling; our margin, "
        "not a contact test, decides.",
        f"- **We exclude, MoveIt checks** ({len(excluded_on)}): the rule says why.",
        "",
    ]
    if rows:
        out += ["| link | link | ours | SRDF | why |", "|---|---|---|---|---|"]
        for r in rows:
            why = (
                f"within {MARGIN:g} m somewhere; the SRDF disables it ({SRDF_WHY[r.srdf]})"
                if r.ours == "watched"
                else WHY[r.ours]
            )
            out.append(f"| {r.a} | {r.b} | {r.ours} | {r.srdf or 'checked'} | {why} |")
        out.append("")
    return "\n".join(out)


def page() -> str:
    """The whole page."""
    head = [
        "# Our self-collision pairs and MoveIt's SRDFs",
        "",
        "Generated by `python docs/srdf_differences.py` (checked by "
        "`tests/docs/test_srdf_differences.py`). For each example-robot-data arm with an "
        f"SRDF: our automatic pairs (margin {MARGIN:g} m, {SAMPLES} random configurations, "
        "seed 0, clouds covering the shapes within 1 cm, distances conservative by both "
        "clouds' resolutions) against the SRDF's "
        "`disable_collisions`, pair by pair where they differ. MoveIt disables a pair that "
        "never *touches* in its sampling (Never), or that one joint joins (Adjacent); we "
        "watch every pair that comes within the margin, so we watch pairs it disables and "
        "exclude pairs it checks when they never come that close.",
        "",
    ]
    return "\n".join(head + [section(arm) for arm in ARMS])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare instead of writing")
    args = parser.parse_args()
    logging.disable(logging.WARNING)
    text = page()
    if args.check:
        same = PAGE.is_file() and PAGE.read_text() == text
        print("up to date" if same else f"{PAGE} differs from what it computes")
        return 0 if same else 1
    PAGE.write_text(text)
    print(f"wrote {PAGE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
