"""The docs page of where our self-collision pairs and example-robot-data's SRDFs differ
is true: every row's SRDF column is what the SRDF file says (read with ElementTree), every
arm has its section, and one arm's section (the UR5's) recomputed equals the page's."""

from __future__ import annotations

import importlib.util
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from types import ModuleType

import pytest

from tests._real_arms import ERD, needs_erd

pytestmark = needs_erd
SCRIPT = Path(__file__).parents[2] / "docs" / "srdf_differences.py"


def _script() -> ModuleType:
    spec = importlib.util.spec_from_file_location("srdf_differences", SCRIPT)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # its dataclass looks its module up
    spec.loader.exec_module(mod)
    return mod


def _sections(text: str) -> dict[str, str]:
    parts = re.split(r"^## ", text, flags=re.M)[1:]
    return {p.split("\n", 1)[0].strip(): "## " + p.rstrip("\n") for p in parts}


def test_every_row_says_what_the_srdf_says() -> None:
    assert ERD is not None
    mod = _script()
    sections = _sections(mod.PAGE.read_text())
    assert set(sections) == set(mod.ARMS)
    for arm, text in sections.items():
        root = ET.parse(ERD / mod.ARMS[arm][1]).getroot()
        reason = {
            frozenset((e.get("link1"), e.get("link2"))): e.get("reason", "User")  # MoveIt default
            for e in root.iter("disable_collisions")
        }
        rows = [line for line in text.splitlines() if line.startswith("| ") and "---" not in line]
        for line in rows[1:]:
            a, b, ours, srdf = (c.strip() for c in line.strip("|").split("|")[:4])
            said = reason.get(frozenset((a, b)))
            assert srdf == (said or "checked"), (arm, a, b)
            assert (ours == "watched") == (said is not None), (arm, a, b)  # a real difference


@pytest.fixture(scope="module")
def ur5() -> tuple[str, str]:
    """The page's UR5 section and the one the script computes now."""
    mod = _script()
    return _sections(mod.PAGE.read_text())["ur5"], mod.section("ur5").rstrip("\n")


def test_the_ur5_section_is_what_the_script_computes(ur5: tuple[str, str]) -> None:
    page, computed = ur5
    assert computed == page


def test_the_comparison_sees_a_changed_row(ur5: tuple[str, str]) -> None:
    """The comparison above on a known violation: a row whose SRDF reason is edited."""
    page, computed = ur5
    edited = page.replace("| watched | User |", "| watched | Never |", 1)
    assert edited != page and computed != edited
