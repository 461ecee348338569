"""The reach-set planner's scenario options, typed (a pydantic model; SI units).

``period`` [s]: the movement period of the automaton; ``constraint_margin`` [m]: the safety-margin
ring of constraints; ``constraint_mode``: ``polygon`` (exact) or ``circle`` (the thesis' Welzl
barrel); ``intruder_margin`` [m]: added to every intruder's body radius; ``intruder_margin_vertical``
[m]: every intruder body stretched by this up and down (a vertical capsule), the allowance for
the ownship's vertical navigation error; ``stop_and_wait``: a multirotor may stop for a movement
period in emergency mode and then fly on facing the goal (D-23); ``separations``: planar
separations of ACAS-like reach sets (spec §4.8, e.g. ["horizontal"], the thesis' S1-S4) used in
both modes instead of the 3-D harmonic / combined sets.
"""

from __future__ import annotations

import dataclasses
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from avoidance.reachset.config import AvoidanceConfig, ConstraintConfig, ExpansionConfig, ReachSetConfig
from avoidance.reachset.movement import (
    KinState,
    SegmentedMovementAutomaton,
    haps_automaton,
    multirotor_automaton,
)

Separation = Literal["horizontal", "vertical", "slash", "backslash"]


class ReachSetOptions(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    period: Annotated[float, Field(gt=0.0)] = 1.0
    constraint_margin: Annotated[float, Field(ge=0.0)] | None = None
    constraint_mode: Literal["polygon", "circle"] | None = None
    intruder_margin: Annotated[float, Field(ge=0.0)] | None = None
    intruder_margin_vertical: Annotated[float, Field(ge=0.0)] | None = None
    stop_and_wait: bool = False
    separations: Annotated[list[Separation], Field(min_length=1)] | None = None

    def avoidance_config(self) -> AvoidanceConfig:
        """The avoidance configuration these options select (defaults elsewhere)."""
        cfg = AvoidanceConfig()
        if self.constraint_margin is not None:
            cfg = dataclasses.replace(cfg, constraints=ConstraintConfig(safety_margin=self.constraint_margin))
        if self.constraint_mode is not None:
            cfg = dataclasses.replace(cfg, constraints=dataclasses.replace(cfg.constraints, mode=self.constraint_mode))
        if self.intruder_margin is not None:
            cfg = dataclasses.replace(
                cfg, intruders=dataclasses.replace(cfg.intruders, body_margin=self.intruder_margin)
            )
        if self.intruder_margin_vertical is not None:
            cfg = dataclasses.replace(
                cfg, intruders=dataclasses.replace(cfg.intruders, vertical_margin=self.intruder_margin_vertical)
            )
        if self.stop_and_wait:
            cfg = dataclasses.replace(cfg, mission=dataclasses.replace(cfg.mission, stop_and_wait=True))
        if self.separations is not None:
            acas = ReachSetConfig.single(ExpansionConfig.acas(tuple(self.separations)))
            cfg = dataclasses.replace(cfg, navigation=acas, avoidance=acas)
        return cfg

    def automaton(
        self, airframe_kind: str, cruise: float, bank_limit_rad: float = float(np.radians(20.0))
    ) -> SegmentedMovementAutomaton:
        """The movement automaton of an ``airframe_kind`` vehicle at ``cruise`` [m/s]."""
        if airframe_kind == "multirotor":
            return multirotor_automaton(cruise, self.period)
        return haps_automaton(cruise, self.period, bank_limit_rad)

    def grid_range(self, airframe_kind: str, cruise: float) -> float:
        """Range [m] of the avoidance grid flown at ``cruise`` [m/s]: layers x the movement length
        of the active segment (a sensor that must see the grid needs at least this)."""
        sma = self.automaton(airframe_kind, cruise)
        length = sma.active(KinState(np.zeros(3), np.zeros(3), 0.0, cruise)).table.config.length
        return float(self.avoidance_config().grid.scaled(length).d_range[1])
