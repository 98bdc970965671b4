"""A robot read from a URDF speaks in the URDF's link names everywhere: its frames and
bodies, the scenario's ``links:`` and ``tool_links:``, the log, the pairs file, the
summary and the report. An unknown name lists the valid ones and the closest match."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import typer
import yaml
from typer.testing import CliRunner

import reachwise
from reachwise.cli.simulate import simulate
from reachwise.errors import InputError
from tests._real_arms import arm_path, needs_erd

pytestmark = needs_erd

#: a generated name (link_3, "arm/tool") where a URDF name belongs
GENERATED = re.compile(r"\blink_\d+\b|arm/tool\b")

UR5 = ["base_link", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link",
       "wrist_2_link", "wrist_3_link", "ee_link"]  # fmt: skip
PANDA = [f"panda_link{i}" for i in range(8)] + ["panda_hand", "panda_leftfinger",
                                                "panda_rightfinger"]  # fmt: skip


def test_frames_and_bodies_carry_the_urdf_names() -> None:
    r = reachwise.load_robot(arm_path("ur5"), tip="tool0")
    assert r.link_names == ("base_link", *UR5[1:7], "tool0")
    assert set(r.geometry) == set(UR5)
    assert r.frame_of("ee_link") == "wrist_3_link"  # fixed to the last link: rides on it
    assert r.link_index("ee_link") == r.link_index("wrist_3_link") == 6
    assert r.link_index("tool") == r.link_index("tool0") == 7
    assert r.body_tree["ee_link"].parent == "wrist_3_link"
    assert r.body_tree["ee_link"].joint == "ee_fixed_joint"
    clouds = reachwise.link_clouds(r, points=50)
    assert list(clouds) == UR5 and clouds["ee_link"].frame == "wrist_3_link"
    with pytest.raises(
        InputError, match=r"unknown link 'wrist_3_lnk'.*did you mean 'wrist_3_link'"
    ):
        r.link_index("wrist_3_lnk")


def _outputs(tmp_path: Path, scenario: str) -> dict[str, str]:
    app = typer.Typer()
    app.command()(simulate)
    args = [scenario, "--duration", "0.3", "--out", str(tmp_path), "--no-figures", "--json"]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    log = np.load(tmp_path / "avoidance" / "log.npz")
    return {
        "stdout": res.stdout,
        "log pairs": " ".join(str(p) for p in log["pairs"]),
        "log.csv": (tmp_path / "avoidance" / "log.csv").read_text(),
        "pairs file": (tmp_path / "self-pairs-arm.yaml").read_text(),
        "summary": (tmp_path / "summary.json").read_text(),
        "report": (tmp_path / "report.html").read_text(),
    }


@pytest.mark.parametrize(("scenario", "names"), [("ur5-box", UR5), ("panda-shelf", PANDA)])
def test_every_output_of_a_urdf_scenario_uses_urdf_link_names(
    tmp_path: Path, scenario: str, names: list[str]
) -> None:
    out = _outputs(tmp_path, scenario)
    for what, text in out.items():
        assert not GENERATED.search(text), (what, GENERATED.search(text))
    pairs = yaml.safe_load(out["pairs file"])
    listed = {n for e in pairs["watched"] + pairs["excluded"] for n in (e["a"], e["b"])}
    assert listed == set(names)
    watched = {f"arm/{e['a']}|arm/{e['b']}" for e in pairs["watched"]}
    assert watched <= set(out["log pairs"].split())
    summary = json.loads(out["summary"])
    assert "arm/" in json.dumps(summary)
    assert any(f"arm/{n}" in out["report"] for n in names)


def test_an_unknown_link_in_a_scenario_lists_the_valid_ones(tmp_path: Path) -> None:
    text = (Path(reachwise.__file__).parent / "data/scenarios/ur5-box.yaml").read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("tool_links: [wrist_3_link, ee_link]", "links: [wrist_3_lnk]"))
    with pytest.raises(InputError) as info:
        reachwise.simulate(bad)
    msg = str(info.value)
    assert str(bad) in msg and "robots.arm.links" in msg and "wrist_3_lnk" in msg
    assert "valid: " in msg and "did you mean 'wrist_3_link'" in msg and "ee_link" in msg
