"""The synthesis report's clearance: the section lists every pose's smallest clearance and
pair as the result holds them and the poses left out; the clearance colouring marks a
pose below the required clearance red and no other."""

from __future__ import annotations

import re

import numpy as np
import pytest
from matplotlib.colors import to_rgba

from reachwise import load_task, synthesize
from reachwise.report.plots import clearance_figure
from reachwise.report.synthesis import synthesis_figures, synthesis_html
from reachwise.synthesis.synthesize import SynthesisResult


@pytest.fixture(scope="module")
def result() -> SynthesisResult:
    task = load_task("tunnel-87")
    task = task.subset([i for i, n in enumerate(task.names) if n.startswith("P01/")])
    res = synthesize(task, "sb60", runs=1, seed=0, clearance=0.1)
    assert res.reached.all() and res.unservable
    return res


def test_section_lists_every_pose_and_the_left_out_ones(result: SynthesisResult) -> None:
    html = synthesis_html(result, figures=None)
    assert 'id="clearance"' in html and 'id="clearance-table"' in html
    table = html.split('id="clearance-table"')[1].split("</table>")[0]
    rows = re.findall(r"<tr[^>]*>(.*?)</tr>", table, flags=re.S)[1:]  # without the head
    best = result.best
    assert best.clearance is not None
    assert len(rows) == result.problem.K
    for row, name, c, pair in zip(
        rows, result.problem.task.names, best.clearance, best.clearance_pairs, strict=True
    ):
        assert name in row and " ~ ".join(pair) in row
        assert f"{c:.4g}"[:4] in row  # the value as the table prints it
    unservable = html.split('id="unservable"')[1].split("</table>")[0]
    for u in result.unservable:
        assert u.name in unservable


def test_clearance_figure_is_in_the_report_figures(result: SynthesisResult) -> None:
    figs = synthesis_figures(result)
    assert list(figs) == ["configurations", "clearance", "lci"]


def test_the_colouring_marks_exactly_the_poses_below_the_clearance(
    result: SynthesisResult,
) -> None:
    prob, best = result.problem, result.best
    c = np.linspace(0.05, 0.5, prob.K)  # some below 0.1, some above
    fig = clearance_figure(best.robot, best.q, prob.task.poses, c, 0.1, every=1)
    ax = fig.axes[0]
    red = to_rgba("tab:red")
    lines = [ln for ln in ax.lines]
    assert len(lines) == prob.K
    is_red = [to_rgba(ln.get_color()) == red for ln in lines]
    assert is_red == list(c < 0.1)
