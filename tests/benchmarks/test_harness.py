"""The benchmark harness on known samples: the medians, tails and ratios the README
quotes come from here, and ``reachwise bench NAME --json`` prints DESIGN.md's shape."""

from __future__ import annotations

import json
import math
import re
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from reachwise.benchmarks import REGISTRY
from reachwise.benchmarks._harness import BenchReport, Target, time_calls, time_interleaved
from reachwise.cli import app
from reachwise.errors import UnknownName

TOP_KEYS = {"benchmark", "machine", "metrics", "ratios", "targets"}


def _number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


def check_schema(obj: Any, name: str) -> None:
    """DESIGN.md "Benchmark output": one object with these keys (and free-text notes)."""
    assert isinstance(obj, dict) and TOP_KEYS <= obj.keys() <= TOP_KEYS | {"notes"}, obj.keys()
    assert obj["benchmark"] == name
    assert isinstance(obj["machine"], dict) and obj["machine"]
    assert all(isinstance(k, str) for k in obj["machine"])
    assert obj["metrics"], "a benchmark reports figures"
    for key, value in obj["metrics"].items():
        assert re.fullmatch(r"[\w\-]+(\.[\w\-]+)*\.\w+", key), key  # <method>.<figure>
        assert _number(value), (key, value)
    for key, value in obj["ratios"].items():
        assert re.fullmatch(r".+_over_.+", key) and _number(value), (key, value)
    for key, target in obj["targets"].items():
        assert isinstance(target, dict) and target.keys() == {"value", "limit", "met"}, key
        assert _number(target["value"]) and _number(target["limit"]), key
        assert isinstance(target["met"], bool), key
    assert all(isinstance(n, str) for n in obj.get("notes", []))


def test_medians_and_tails_of_known_samples() -> None:
    r = BenchReport("t")
    r.add_samples("m", np.random.default_rng(0).permutation(np.arange(1.0, 101.0)))
    # 1..100: the median halves 50 and 51; the p99 lies 0.01 of the way from 99 to 100
    # (linear interpolation at rank 0.99 * 99 = 98.01), the p99.9 0.901 of the way
    assert r.metrics["m.median"] == 50.5
    assert math.isclose(r.metrics["m.p99"], 99.01, rel_tol=1e-12)
    assert math.isclose(r.metrics["m.p99_9"], 99.901, rel_tol=1e-12)
    assert r.metrics["m.mean"] == 50.5 and r.metrics["m.count"] == 100
    # one slow call in a hundred: the median does not see it, the tail does
    r.add_samples("s", np.array([10.0] * 99 + [1000.0]))
    assert r.metrics["s.median"] == 10.0
    assert math.isclose(r.metrics["s.p99"], 10.0 + 0.01 * 990.0, rel_tol=1e-12)
    assert math.isclose(r.metrics["s.mean"], (990.0 + 1000.0) / 100, rel_tol=1e-12)
    r.add_samples("one", np.array([7.0]))
    assert r.metrics["one.median"] == r.metrics["one.p99"] == 7.0


def test_ratios_name_their_methods_and_divide_the_figure() -> None:
    r = BenchReport("t")
    r.add_samples("a", np.array([30.0, 30.0, 30.0]))
    r.add_samples("b", np.array([12.0, 12.0, 100.0]))
    assert r.ratio("a", "b") == 2.5  # medians 30 / 12
    assert r.ratios == {"a_over_b": 2.5}
    assert math.isclose(r.ratio("b", "a", "p99"), (12.0 + 0.98 * 88.0) / 30.0, rel_tol=1e-12)
    assert r.ratios["b_over_a"] == r.ratio("b", "a", "p99")
    with pytest.raises(KeyError):
        r.ratio("a", "missing")


@pytest.mark.parametrize(
    ("value", "limit", "higher", "met"),
    [
        (5.0, 10.0, False, True),
        (10.0, 10.0, False, True),  # on the limit: met
        (10.5, 10.0, False, False),
        (10.0, 10.0, True, True),
        (9.9, 10.0, True, False),
        (math.nan, 10.0, False, False),  # a failed measurement never meets a target
        (math.inf, 10.0, True, False),
    ],
)
def test_targets(value: float, limit: float, higher: bool, met: bool) -> None:
    assert Target(value, limit, higher).met is met


def test_time_calls_calls_warmup_then_repeat_times() -> None:
    calls: list[int] = []
    samples = time_calls(lambda: calls.append(1), repeat=25, warmup=4)
    assert len(calls) == 29 and samples.shape == (25,)
    assert np.all(np.isfinite(samples)) and np.all(samples >= 0.0)


def test_time_interleaved_puts_the_methods_side_by_side() -> None:
    order: list[tuple[str, int]] = []
    fns = {k: (lambda i, k=k: order.append((k, i))) for k in ("a", "b", "c")}
    out = time_interleaved(fns, repeat=3, warmup=2)
    expected = [(k, i) for i in (0, 1) for k in "abc"] + [(k, i) for i in (0, 1, 2) for k in "abc"]
    assert order == expected  # query by query, every method in turn
    assert out.keys() == fns.keys() and all(v.shape == (3,) for v in out.values())


def test_bench_json_of_known_samples(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(REGISTRY, "known", "tests.benchmarks.known_bench")
    res = CliRunner().invoke(app, ["bench", "known", "--json", "--quick"])
    assert res.exit_code == 0, res.output
    obj = json.loads(res.stdout)
    check_schema(obj, "known")
    m = obj["metrics"]
    assert m["ours.query.median"] == 50.5 and math.isclose(m["ours.query.p99"], 99.01)
    assert m["baseline.query.median"] == 10.0 and math.isclose(m["baseline.query.p99"], 19.9)
    assert obj["ratios"] == {"baseline.query_over_ours.query": 10.0 / 50.5}
    assert obj["targets"] == {"ours.query.median": {"value": 50.5, "limit": 60.0, "met": True}}
    assert obj["notes"] == ["quick"]
    # the human table shows the same figures
    table = CliRunner().invoke(app, ["bench", "known"], env={"COLUMNS": "200"})
    assert table.exit_code == 0, table.output
    for key, value in m.items():
        assert re.search(rf"{re.escape(key)}\s.*\s{re.escape(f'{value:.4g}')}", table.stdout), key
    assert "baseline.query_over_ours.query" in table.stdout and "0.198" in table.stdout


def test_bench_json_of_a_real_benchmark_has_the_design_shape() -> None:
    res = CliRunner().invoke(app, ["bench", "kinematics", "--quick", "--json"])
    assert res.exit_code == 0, res.output
    obj = json.loads(res.stdout)
    check_schema(obj, "kinematics")
    assert obj["ratios"] and obj["targets"]


def test_unknown_benchmark_is_refused() -> None:
    res = CliRunner().invoke(app, ["bench", "no-such-bench", "--json"])
    assert isinstance(res.exception, UnknownName) and res.exception.exit_code == 2
    assert "no-such-bench" in str(res.exception) and "kinematics" in str(res.exception)


def test_bench_json_is_standard_json_when_a_figure_is_not_finite() -> None:
    rep = BenchReport("gaps")
    rep.metrics["measured"] = 1.5
    rep.metrics["not_measured"] = math.nan
    rep.metrics["beyond_last_bucket"] = math.inf
    rep.targets["t"] = Target(math.nan, 2.0)

    def refuse(name: str) -> float:
        raise AssertionError(f"{name} is not JSON")

    obj = json.loads(rep.to_json(), parse_constant=refuse)
    assert obj["metrics"] == {"measured": 1.5, "not_measured": None, "beyond_last_bucket": None}
    assert obj["targets"]["t"] == {"value": None, "limit": 2.0, "met": False}
