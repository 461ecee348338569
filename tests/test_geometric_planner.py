"""GeometricAvoider behind the shared planner protocol: NED in/out, reference when clear,
avoidance plan, commitment re-check, NO_SOLUTION hover, candidate log, invalid inputs."""

from __future__ import annotations

import json

import numpy as np
import pytest

from avoidance.geometric.config import GeometricConfig
from avoidance.geometric.planner import GeometricAvoider
from avoidance.planner import Plan, PlanStatus, Planner, Threats
from avoidance.threats import IntruderTrack, SphereThreat
from sim.state import VehicleState

REF = np.array([[0.0, 0.0, -20.0], [50.0, 0.0, -20.0], [120.0, 0.0, -20.0]])   # north at 20 m


def state(t: float, north: float, east: float = 0.0) -> VehicleState:
    return VehicleState(t, np.array([north, east, -20.0]), np.array([5.0, 0, 0]), np.zeros(3), np.zeros(3), 20.0, 47.0, 8.0)


def sphere(north: float, east: float = 0.0, r: float = 2.0, **kw) -> SphereThreat:
    return SphereThreat(kw.pop("id", "s"), kw.pop("t", 0.0), np.array([north, east, -20.0]), r, **kw)


def test_protocol_and_reference_when_clear():
    av: Planner = GeometricAvoider(REF, 5.0)
    assert av.name == "geometric"
    p = av.plan(state(1.0, 10.0, 0.4), Threats(spheres=[sphere(60.0, 20.0)]), 1.0)
    assert p.status is PlanStatus.OK and p.diagnostics["status"] == "no_conflict"
    assert np.allclose(p.positions, [[10, 0, -20], [50, 0, -20], [120, 0, -20]])
    assert np.allclose(p.times, [1, 9, 23]) and list(p.labels) == [-1, 1, 2]
    assert p.diagnostics["cross_track_m"] == pytest.approx(0.4)


def test_avoidance_plan_leaves_and_rejoins_the_reference():
    av = GeometricAvoider(REF, 5.0, GeometricConfig(start_shift_s=0.5))
    p = av.plan(state(2.0, 10.0), Threats(spheres=[sphere(25.0)]), 2.0)
    d = p.diagnostics
    assert p.status is PlanStatus.OK and d["status"] == "avoid" and d["n_candidates"] == 32
    assert d["main_threat_id"] == "s" and d["cost"] > 0 and 0 <= d["chosen_index"] < 32
    assert {"t_generation_s", "t_collision_s", "t_cost_s", "t_total_s"} <= d.keys()
    assert np.allclose(p.positions[0], [10, 0, -20]) and p.times[0] == 2.0
    assert np.allclose(p.positions[1], [12.5, 0, -20]) and p.times[1] == pytest.approx(2.5)   # latency shift
    assert np.all(np.diff(p.times) > 0) and np.allclose(p.positions[-1], REF[-1]) and p.labels[-1] == 2
    off = np.hypot(p.positions[:, 1], p.positions[:, 2] + 20)
    assert off.max() == pytest.approx(abs(av.candidate_log()["omega_m"][d["chosen_index"]]))
    # clear of the (static) threat by R + r_uav along the plan's polyline
    u = np.linspace(0, 1, 50)[None, :, None]
    dense = (p.positions[:-1, None] + np.diff(p.positions, axis=0)[:, None] * u).reshape(-1, 3)
    assert np.linalg.norm(dense - [25, 0, -20], axis=1).min() >= 3.0 - 1e-9
    assert p.velocities.shape == p.positions.shape and np.allclose(p.velocities[-1], 0)


def test_commitment_kept_while_valid_and_replanned_when_invalid():
    av = GeometricAvoider(REF, 5.0, GeometricConfig(start_shift_s=0.0))
    threats = Threats(spheres=[sphere(25.0)])
    first = av.plan(state(0.0, 10.0), threats, 0.0)
    k = first.diagnostics["chosen_index"]
    again = av.plan(state(0.5, 12.5), threats, 0.5)
    assert again.diagnostics["status"] == "committed" and np.array_equal(again.positions, first.positions)
    assert av.still_valid(threats, 0.5)
    # a new sphere right on the committed path's peak
    peak = first.positions[np.argmax(np.hypot(first.positions[:, 1], first.positions[:, 2] + 20))]
    blocked = Threats(spheres=[sphere(25.0), SphereThreat("new", 0.5, peak.copy(), 1.0)])
    assert not av.still_valid(blocked, 0.5)
    re = av.plan(state(0.5, 12.5), blocked, 0.5)
    assert re.diagnostics["replan_reason"] == "invalid"
    assert re.status is PlanStatus.NO_SOLUTION or re.diagnostics["chosen_index"] != k


def test_no_solution_hovers_and_too_close_hovers():
    av = GeometricAvoider(REF, 5.0, GeometricConfig(start_shift_s=0.0))
    # a ring of spheres abreast of the main threat at 4.8 m, in the 8 directions of the planes:
    # every candidate peak (3.2 or 6.4 m off the reference) passes within 1.6 m of a centre
    ring = [SphereThreat(f"r{i}", 0.0, np.array([25.0, 4.8 * np.cos(a), -20 + 4.8 * np.sin(a)]), 2.0)
            for i, a in enumerate(np.radians(np.arange(0, 360, 45)))]
    p = av.plan(state(3.0, 10.0), Threats(spheres=[sphere(25.0)] + ring), 3.0)
    assert p.status is PlanStatus.NO_SOLUTION and p.diagnostics["status"] == "no_solution"
    assert np.allclose(p.positions, [[10, 0, -20]]) and np.allclose(p.velocities, 0) and p.times[0] == 3.0
    p = av.plan(state(3.0, 10.0), Threats(spheres=[sphere(14.0)]), 3.0)
    assert p.status is PlanStatus.NO_SOLUTION and p.diagnostics["status"] == "too_close"


def test_intruder_track_with_covariance_and_candidate_log():
    cfg = GeometricConfig(start_shift_s=0.0, k_sigma=2.0)
    av = GeometricAvoider(REF, 5.0, cfg)
    head_on = IntruderTrack("ac1", 0.0, np.array([60.0, 0, -20]), np.array([-5.0, 0, 0]), 1.0,
                            pos_cov=np.eye(3) * 0.25, vel_cov=np.eye(3) * 0.01)
    p = av.plan(state(0.0, 10.0), Threats(intruders=[head_on]), 0.0)
    assert p.diagnostics["main_threat_id"] == "ac1"
    assert p.diagnostics["t_cpa_s"] == pytest.approx(5.0)
    log = av.candidate_log()
    text = json.dumps(log)                                             # plain JSON
    assert np.array(log["points_ned"]).shape == (32, 21, 3) and len(log["cost"]) == 32
    assert set(log["raw"]) == {"time", "energy", "smoothness", "smoothness_rp", "cmo", "hover_power"}
    assert set(log["normalised"]) == {"time", "energy", "smoothness_rp", "cmo"}
    assert "NaN" not in text and log["chosen"] == p.diagnostics.get("chosen_index")


def test_invalid_inputs_raise_clear_errors():
    with pytest.raises(ValueError, match="straight"):
        GeometricAvoider(np.array([[0, 0, 0], [10, 0, 0], [20, 5, 0]]), 5.0)
    with pytest.raises(ValueError, match="speed"):
        GeometricAvoider(REF, -1.0)
    with pytest.raises(ValueError, match="advance"):
        GeometricAvoider(np.array([[0, 0, 0], [20, 0, 0], [10, 0, 0], [30, 0, 0]]), 5.0)
    with pytest.raises(RuntimeError, match="reference"):
        GeometricAvoider().plan(state(0, 0), Threats(), 0.0)
    av = GeometricAvoider(REF, 5.0)
    with pytest.raises(ValueError, match="radius"):
        av.plan(state(0, 10), Threats(spheres=[sphere(30.0, r=-1.0)]), 0.0)
    with pytest.raises(ValueError, match="covariance"):
        GeometricAvoider(REF, 5.0, GeometricConfig(k_sigma=2.0)).plan(
            state(0, 10), Threats(spheres=[sphere(30.0, center_cov=-np.eye(3))]), 0.0)
    assert isinstance(av.plan(state(0, 10), Threats(), 0.0), Plan)
