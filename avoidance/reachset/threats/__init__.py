"""Per-source threat ratings written into the Avoidance Grid (spec §5.1-5.5).

Each function takes the grid, its pose (LCF placed in the z-up GCF) and the project's sensed
threat types (NED, ``sim.core.threats``), and returns per-cell arrays (ratings in [0, 1] or masks).
"""
