"""Scenario options of a reach-set planner flying under the rules of the air: the reach-set
options plus ``rules`` (the enabled rule codes) and ``rules_<field>`` for every other field of
:class:`avoidance.rules.config.RulesConfig` (in its units). Without ``rules`` the vehicle is a
plain reach-set avoider and ``rules_<field>`` options are an error."""

from __future__ import annotations

from typing import Any

from pydantic import create_model, model_validator

from avoidance.reachset.options import ReachSetOptions
from avoidance.rules.config import RULES_FIELDS, RulesConfig


class _RulesOptionsBase(ReachSetOptions):
    rules: list[str] | None = None

    def rules_config(self) -> RulesConfig | None:
        """The rules configuration, or None for a plain reach-set avoider."""
        if self.rules is None:
            return None
        table = {
            name: getattr(self, f"rules_{name}") for name in RULES_FIELDS if f"rules_{name}" in self.model_fields_set
        }
        return RulesConfig.from_options({"enabled": self.rules, **table})

    @model_validator(mode="after")
    def _rules_table(self) -> _RulesOptionsBase:
        given = sorted(k for k in self.model_fields_set if k.startswith("rules_"))
        if given and self.rules is None:
            raise ValueError(f"{', '.join(given)} need rules (the enabled rules of the air)")
        self.rules_config()  # RulesConfig checks the values, naming the field
        return self


_RULES_FIELDS: dict[str, Any] = {f"rules_{name}": (Any, None) for name in RULES_FIELDS}  # checked by RulesConfig
RulesOptions = create_model("RulesOptions", __base__=_RulesOptionsBase, **_RULES_FIELDS)
