"""Guidance: missions and waypoints, path following, turning-flight geometry, MPTP."""
