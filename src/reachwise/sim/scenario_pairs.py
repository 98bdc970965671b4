"""A scenario's ``watch:`` section: the pairs watched and their collision margins,
self pairs of a robot's links included (listed, ``auto`` or from an SRDF)
(:mod:`reachwise.sim.scenarios` holds the whole schema)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, model_validator

from reachwise.io.validation import StrictModel
from reachwise.sim.scenario_fields import STRICT

__all__ = ["SrdfPairsSpec", "WatchSpec"]


class SrdfPairsSpec(StrictModel):
    """``pairs: {srdf: FILE}``: every pair of the robot's link clouds that the MoveIt
    SRDF ``FILE`` (relative to the scenario) does not disable
    (:mod:`reachwise.sim.srdf_inputs`)."""

    model_config = STRICT
    srdf: str = Field(min_length=1)


class WatchSpec(StrictModel):
    """``self: R`` (pairs among R's links; ``pairs`` lists link pairs, ``pairs: auto``
    picks them (:mod:`reachwise.sim.self_pairs`: adjacent and never-close pairs
    excluded over ``samples`` random configurations, ``seed``), ``pairs: {srdf: FILE}``
    watches all but the pairs a MoveIt SRDF disables, else every
    non-adjacent pair of ``links``; ``self: {robot: R, pairs: auto}`` is the same),
    ``robot: R, environment: [objects]`` or ``robots: [A, B]``; ``links`` restricts
    the robots' links, ``margin`` is ρ_O."""

    model_config = STRICT
    self_: str | None = Field(default=None, alias="self")
    robot: str | None = None
    environment: list[str] | None = None
    robots: tuple[str, str] | None = None
    links: list[str] | None = None
    pairs: list[tuple[str, str]] | Literal["auto"] | SrdfPairsSpec | None = None
    samples: int = Field(default=10_000, ge=1)
    seed: int = Field(default=0, ge=0)
    margin: float = Field(gt=0.0)

    @model_validator(mode="before")
    @classmethod
    def _nested_self(cls, data: Any) -> Any:
        """``self: {robot: R, pairs: …, …}`` is ``self: R, pairs: …, …``."""
        if isinstance(data, dict) and isinstance(data.get("self"), dict):
            inner = dict(data["self"])
            out = {k: v for k, v in data.items() if k != "self"}
            if "robot" not in inner:
                raise ValueError("self: {robot: NAME, …} needs robot")
            out["self"] = inner.pop("robot")
            for k, v in inner.items():
                if k in out:
                    raise ValueError(f"{k} given twice (inside self and beside it)")
                out[k] = v
            return out
        return data

    @model_validator(mode="after")
    def _kind(self) -> WatchSpec:
        kinds = [self.self_ is not None, self.environment is not None, self.robots is not None]
        if sum(kinds) != 1:
            raise ValueError("give exactly one of self, environment (with robot), robots")
        if self.environment is not None and self.robot is None:
            raise ValueError("environment pairs need robot")
        if self.pairs is not None and self.self_ is None:
            raise ValueError("pairs are for self pairs")
        return self

    @property
    def kind(self) -> str:
        if self.self_ is not None:
            return "self"
        return "robot-environment" if self.environment is not None else "robot-robot"
