"""SynthesisSettings is the typed group of synthesize's search settings; each field is
also a keyword (the documented call), and a keyword overrides the group."""

from __future__ import annotations

import numpy as np
import pytest

import reachwise
from reachwise import load_robot, load_task
from reachwise.synthesis.synthesize import SynthesisSettings, synthesize


def test_settings_group_and_keywords_are_one_search() -> None:
    task = load_task("tunnel-87").subset(np.arange(0, 87, 29), name="tunnel-3")
    template = load_robot("sb60")
    settings = SynthesisSettings(runs=1, seed=3, objective={}, init_sets=2)
    by_group = synthesize(task, template, settings)
    by_keywords = synthesize(task, template, runs=1, seed=3, objective={}, init_sets=2)
    np.testing.assert_array_equal(by_group.best.design, by_keywords.best.design)
    assert [r.seed for r in by_group.runs] == [3]
    overridden = synthesize(task, template, settings, seed=4, runs=2)  # keywords win
    assert [r.seed for r in overridden.runs] == [4, 5]
    with pytest.raises(TypeError, match="sed"):
        synthesize(task, template, sed=1)


def test_public_synthesize_keeps_the_settings_group() -> None:
    task = load_task("tunnel-87").subset(np.arange(0, 87, 29), name="tunnel-3")
    settings = SynthesisSettings(runs=1, seed=3, objective={}, init_sets=2)
    kept = reachwise.synthesize(task, "sb60", settings=settings)
    assert [r.seed for r in kept.runs] == [3]  # not the keywords' defaults (10 runs, seed 0)
    overridden = reachwise.synthesize(task, "sb60", settings=settings, seed=5)
    assert [r.seed for r in overridden.runs] == [5]
