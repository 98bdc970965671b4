"""The HTML reports of synthesis, topology and simulation runs: their tables hold the
result's numbers, every figure is an embedded PNG, nothing points outside the file,
user strings are escaped, and each opens in headless chromium without console errors
with every figure decoded."""

from __future__ import annotations

import base64
import html
import io
from dataclasses import replace
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from reachwise import load_robot, load_task
from reachwise.report import (
    thesis,
    write_simulation_report,
    write_synthesis_report,
    write_topology_report,
)

HOSTILE = '<script>alert("x")</script><img src=x onerror=alert(1)>&amp;'


class Page(HTMLParser):
    """Tables (by id: rows of cell texts), images, every URL-bearing attribute, tags."""

    def __init__(self, text: str) -> None:
        super().__init__(convert_charrefs=True)
        self.tables: dict[str, list[list[str]]] = {}
        self.images: list[dict[str, str]] = []
        self.urls: list[str] = []
        self.tags: set[str] = set()
        self.title = ""
        self._table: list[list[str]] | None = None
        self._cell: list[str] | None = None
        self._in_title = False
        self.feed(text)

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = {k: v or "" for k, v in attrs}
        self.tags.add(tag)
        for k in ("href", "src", "action", "srcset", "data"):
            if k in a:
                self.urls.append(a[k])
        if tag == "table":
            self._table = self.tables.setdefault(a.get("id") or f"_{len(self.tables)}", [])
        elif tag == "tr" and self._table is not None:
            self._table.append([])
        elif tag in ("td", "th"):
            self._cell = []
        elif tag == "img":
            self.images.append(a)
        elif tag == "title":
            self._in_title = True

    def handle_endtag(self, tag: str) -> None:
        if tag in ("td", "th") and self._cell is not None and self._table is not None:
            self._table[-1].append("".join(self._cell).strip())
            self._cell = None
        elif tag == "table":
            self._table = None
        elif tag == "title":
            self._in_title = False

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._cell.append(data)
        if self._in_title:
            self.title += data

    def body(self, table: str) -> list[list[str]]:
        """The data rows of a table (header row dropped)."""
        return self.tables[table][1:]


def png_size(uri: str) -> tuple[int, int]:
    from PIL import Image

    assert uri.startswith("data:image/png;base64,")
    data = base64.b64decode(uri.split(",", 1)[1], validate=True)
    img = Image.open(io.BytesIO(data))
    img.verify()  # a valid, complete PNG
    return Image.open(io.BytesIO(data)).size


def check_self_contained(path: Path, figures: int) -> Page:
    text = path.read_text(encoding="utf-8")
    pg = Page(text)
    for u in pg.urls:  # every URL is embedded data or a relative link
        assert u.startswith("data:") or "://" not in u, u
        assert not u.startswith("//"), u
    assert "@import" not in text and "url(" not in text
    assert "http://" not in text and "https://" not in text
    assert "script" not in pg.tags
    assert len(pg.images) == figures
    for img in pg.images:
        w, h = png_size(img["src"])
        assert w > 100 and h > 100
    return pg


def small_task(name: str = "tunnel-6") -> Any:
    return load_task("tunnel-87").subset(np.arange(0, 87, 15), name=name)


# ---- results, built once per module ---------------------------------------------------------
@pytest.fixture(scope="module")
def synthesis() -> Any:
    from reachwise import synthesize

    return synthesize(small_task(), "sb60", runs=2, seed=0)


@pytest.fixture(scope="module")
def sweep() -> Any:
    from reachwise.synthesis.sweep import SweepConfig, run_sweep
    from reachwise.synthesis.topology import builtin_set

    topos = [t for t in builtin_set("p2", load_robot) if t.name in ("p2-man1", "p2-man3")]
    cfg = SweepConfig(subset=3, top=1, runs=1, seed=0)
    return run_sweep(small_task(), topos, cfg, workers=0)


@pytest.fixture(scope="module")
def p5() -> tuple[Any, dict[str, Any]]:
    from reachwise.sim.scenarios import load_scenario
    from reachwise.sim.simulate import simulate

    sc = load_scenario("p5-crane-obstacle")
    logs = {
        "avoidance": simulate(sc, avoidance=True, duration=2.0),
        "baseline": simulate(sc, avoidance=False, duration=2.0),
    }
    return sc, logs


# ---- synthesis ---------------------------------------------------------------------------------
def test_synthesis_report_tables_hold_the_result(synthesis: Any, tmp_path: Path) -> None:
    path = write_synthesis_report(synthesis, tmp_path)
    assert path == tmp_path / "report.html"
    pg = check_self_contained(path, figures=2)
    t3 = pg.body("table3")
    assert [r[0] for r in t3] == list(synthesis.problem.design_names)
    for row, ref in zip(t3, synthesis.table3(), strict=True):
        assert row[1:4] == [
            f"{ref['initial']:.4f}",
            f"{ref['optimized']:.4f}",
            f"{ref['changed_percent']:.2f}",
        ]
        # sb60's design parameters are P-I's: the thesis columns sit next to ours
        assert row[4:7] == [
            f"{v:.4f}" if i < 2 else f"{v:.2f}" for i, v in enumerate(thesis.P1_TABLE3[row[0]])
        ]
    t4 = pg.body("table4")
    for row, ref in zip(t4, synthesis.table4(), strict=True):
        assert row[:4] == [
            ref["parameter"],
            f"{ref['mean']:.4f}",
            f"{ref['std']:.4f}",
            str(ref["runs"]),
        ]
        assert row[4:6] == [f"{v:.4f}" for v in thesis.P1_TABLE4[row[0]]]
    # normalized values really are the design between its bounds
    lo, hi = synthesis.problem.bounds
    p = synthesis.problem.p
    norm = (synthesis.best.design - lo[:p]) / (hi[:p] - lo[:p])
    assert [float(r[2]) for r in t3] == pytest.approx(norm, abs=5e-5)
    runs = pg.body("runs")
    assert [r[0] for r in runs] == [str(r.seed) for r in synthesis.runs]
    K = synthesis.problem.K
    assert [r[1] for r in runs] == [f"{r.n_reached}/{K}" for r in synthesis.runs]
    assert [r[3] for r in runs] == [str(r.iterations) for r in synthesis.runs]
    pts = pg.body("points")
    assert len(pts) == K
    assert [r[6] for r in pts] == list(synthesis.best.status)
    err_mm = [float(r[4]) for r in pts]
    assert err_mm == pytest.approx(synthesis.best.position_error * 1e3, abs=1e-3)
    design = pg.body("design")
    assert [float(r[4]) for r in design] == pytest.approx(synthesis.best.design, abs=1e-4)


def test_dh_table_shows_template_and_found(synthesis: Any, tmp_path: Path) -> None:
    pg = Page(synthesis_html_of(synthesis))
    dh = pg.body("dh")
    tmpl, found = synthesis.problem.template, synthesis.robot
    assert len(dh) == len(tmpl.joints)
    free = {(j, p) for kind, j, p in tmpl.design.free if kind == "joint"}
    cols = {"a": 2, "d": 4}
    for (j, p), c in ((jp, cols[jp[1]]) for jp in free if jp[1] in cols):
        assert dh[j][c] == f"{getattr(tmpl.joints[j], p):.4f} → {getattr(found.joints[j], p):.4f}"
    assert dh[0][1] == tmpl.joints[0].type


def synthesis_html_of(result: Any) -> str:
    from reachwise.report.synthesis import synthesis_html

    return synthesis_html(result, None)


def test_hostile_names_are_escaped(tmp_path: Path, browser: Any) -> None:
    from reachwise.synthesis.synthesize import synthesize

    robot = replace(load_robot("sb60"), name=HOSTILE)
    task = small_task(HOSTILE).subset(np.arange(3), name=HOSTILE)
    result = synthesize(task, robot, runs=1, seed=0)
    path = write_synthesis_report(result, tmp_path, figures=False)
    text = path.read_text()
    assert HOSTILE not in text
    assert "<script" not in text.lower() and "<img src=x" not in text.lower()
    assert html.escape(HOSTILE) in text
    pg = Page(text)
    assert pg.title == f"Synthesis: {HOSTILE} for {HOSTILE}"
    assert pg.images == [] and "script" not in pg.tags
    page = browser.new_page()
    dialogs: list[str] = []
    errors: list[str] = []
    page.on("dialog", lambda d: (dialogs.append(d.message), d.dismiss()))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.goto(path.as_uri())
    assert page.title() == f"Synthesis: {HOSTILE} for {HOSTILE}"
    assert page.locator("img").count() == 0
    assert dialogs == [] and errors == []
    page.close()


# ---- topology ----------------------------------------------------------------------------------
def test_topology_report_ranks_like_the_sweep(sweep: Any, tmp_path: Path) -> None:
    from reachwise.report.ranking import write_report

    data = write_report(sweep, tmp_path)
    path = write_topology_report(sweep, tmp_path, data["designs"])
    # the GCI/KCI chart plus one configuration figure per exported design
    pg = check_self_contained(path, figures=1 + len(data["designs"]))
    rows = pg.body("ranking")
    recs = sweep.final.records()
    assert [r[1] for r in rows] == [r["topology"] for r in recs]
    for row, rec in zip(rows, recs, strict=True):
        assert row[0] == ("–" if rec["rank"] is None else str(rec["rank"]))
        if rec["feasible"]:
            assert row[3:6] == [f"{rec[k]:.4f}" for k in ("gci", "kci", "mean")]
        assert row[9] == f"{rec['reached']}/{rec['points']}"
    r1 = pg.body("round1")
    assert sorted(r[1] for r in r1) == sorted(sweep.topologies)
    assert {r[9] for r in r1} == {f"{len(sweep.subset)}/{len(sweep.subset)}"} | {
        f"{r['reached']}/{r['points']}" for r in sweep.round1.records()
    }
    comp = {r[0]: r for r in pg.body("thesis-topology")}
    g, k, m = thesis.P2_TABLE2["p2-man1"]  # type: ignore[misc]
    assert comp["p2-man1"][1] == f"GCI {g:.4f}, KCI {k:.4f}, mean {m:.4f}"
    best = sweep.ranked()[0]
    assert comp["best by GCI and KCI"][2] == best


# ---- simulation --------------------------------------------------------------------------------
def test_simulation_report_holds_the_logs(p5: Any, tmp_path: Path) -> None:
    from reachwise.report.simulate import leg_lengths, scene_cloud

    sc, logs = p5
    cloud = scene_cloud(sc)
    path = write_simulation_report(tmp_path, sc, logs, True, cloud)
    pg = check_self_contained(path, figures=3)
    out = {r[0]: r for r in pg.body("outcome")}
    base, avoid = logs["baseline"], logs["avoidance"]
    assert base.first_collision is not None and avoid.first_collision is None
    assert out["without avoidance (baseline)"][4] == (
        f"{base.first_collision:.2f} s ({base.first_collision_pair})"
    )
    assert out["with avoidance"][4] == "none"
    md = avoid.min_distance
    assert out["with avoidance"][3] == f"{md[np.isfinite(md)].min() * 100:.1f} cm"
    pairs = {r[0]: r for r in pg.body("pairs")}
    for i, p in enumerate(avoid.pairs):
        v = avoid.signed[:, i].min()
        assert pairs[p][2] == ("–" if not np.isfinite(v) else f"{v * 100:.1f} cm")
    # the thesis's numbers next to ours (P-V)
    comp = {r[0]: r for r in pg.body("thesis-simulation")}
    assert comp["scanned cloud"][2] == f"{len(cloud)} points"
    assert "5500" in comp["scanned cloud"][1]
    assert comp["conventional controller"][2].startswith(f"collides at {base.first_collision:.2f}")
    # no goal is reached in 2 s: the one leg is the whole tool path
    p = avoid.tool["crane"][:, :3, 3]
    whole = float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())
    assert leg_lengths(avoid, "crane")[0][1] == pytest.approx(whole)
    legs = pg.body("legs")
    assert legs[0][3] == f"{whole:.2f}"


def test_p3_report_states_the_thesis_collision_time(tmp_path: Path) -> None:
    from reachwise.sim.scenarios import load_scenario
    from reachwise.sim.simulate import simulate

    sc = load_scenario("p3-self-collision")
    logs = {
        m: simulate(sc, avoidance=m == "avoidance", duration=0.5) for m in ("avoidance", "baseline")
    }
    pg = Page(write_simulation_report(tmp_path, sc, logs, False).read_text())
    comp = {r[0]: r for r in pg.body("thesis-simulation")}
    assert comp["conventional controller (no avoidance)"][1] == "self-collides at 2.16 s (Fig. 3b)"
    assert pg.images == []


# ---- in the browser ------------------------------------------------------------------------------
def test_reports_open_in_chromium_with_their_figures(
    synthesis: Any, sweep: Any, p5: Any, tmp_path: Path, page: Any
) -> None:
    from reachwise.report.ranking import write_report

    sc, logs = p5
    paths = {
        "synthesis": (write_synthesis_report(synthesis, tmp_path / "s"), 2),
        "topology": (
            write_topology_report(
                sweep, tmp_path / "t", write_report(sweep, tmp_path / "t")["designs"]
            ),
            None,
        ),
        "simulate": (write_simulation_report(tmp_path / "m", sc, logs), 3),
    }
    for kind, (path, n) in paths.items():
        page.goto(path.as_uri())
        page.wait_for_load_state("load")
        widths = page.evaluate(
            "Array.from(document.images).map(i => i.complete ? i.naturalWidth : -1)"
        )
        assert widths and all(w > 0 for w in widths), (kind, widths)
        if n is not None:
            assert len(widths) == n, kind
        assert page.locator("table").count() >= 3, kind
        assert page.console_errors == [], (kind, page.console_errors)
