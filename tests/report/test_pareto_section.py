"""The Pareto section says what its table's designs reach: every pose for all, or how
many of them, never "every design" when a row of the table did not."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any, cast

import pytest

from reachwise.report.design import pareto_section


def _row(index: int, reached: int, points: int, front: bool) -> dict[str, Any]:
    return {
        "index": index, "weights": {"gci": 0.5, "size": 0.5},
        "values": {"gci": 0.1 + index / 100, "size": 3.0 - index / 10, "kci": 0.05},
        "reached": reached, "points": points, "front": front, "bound_hits": [],
        "design_yaml": f"pareto/{index}/design.yaml", "design_urdf": f"pareto/{index}/d.urdf",
    }  # fmt: skip


@pytest.mark.parametrize(
    ("reached", "said"),
    [
        ((6, 6, 6), "Every design reaches every pose."),
        ((6, 4, 6), "2 of 3 designs reach every pose"),
        ((0, 4, 5), "0 of 3 designs reach every pose"),
    ],
)
def test_the_section_counts_the_designs_that_reach(reached: tuple[int, ...], said: str) -> None:
    rows = [_row(i, r, 6, r == 6) for i, r in enumerate(reached)]
    data = {"points": rows, "front_size": sum(r["front"] for r in rows)}
    result = cast(Any, SimpleNamespace(names=("gci", "size")))
    html = str(pareto_section(result, data))
    assert said in html
    if said.startswith("Every"):
        assert "designs reach every pose" not in html
    else:
        assert "Every design reaches every pose" not in html
