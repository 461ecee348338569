"""Avoidance planners: the reach-set avoidance grid with the rules of the air and UTM, the geometric
candidate-path avoider (the planner protocol and Plan are sim.core.plan)."""
