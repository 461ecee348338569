"""The shared vocabulary, on the ground floor: every type that crosses a package boundary.

``state`` (VehicleState), ``frames`` (NED/ENU, Euler angles, rotation matrices, quaternions),
``constants`` (gravity, unit factors), ``plan`` (Plan, PlanStatus, Threats, the Planner protocol),
``threats`` (what a vehicle senses), ``mission`` (waypoint missions), ``setpoints`` (guidance ->
flight controller). It imports numpy and the standard library only; ``aircraft``, ``guidance`` and
``avoidance`` import nothing else from ``sim`` (tests/test_layering.py).
"""
