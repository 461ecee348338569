"""Planners: the common planner interface, reach-set avoidance grid, geometric avoider."""
