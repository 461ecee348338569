"""GeometricAvoider behind the shared planner protocol: NED in/out, reference when clear,
avoidance plan, commitment re-check, NO_SOLUTION hover, candidate log, invalid inputs, and the
closed-loop rules: selection margin (hysteresis), collision point of a static threat beyond the
detection horizon, progress-based commitment, latency shift at the vehicle's speed, minimum
re-plan interval, suspended path."""

from __future__ import annotations

import json

import numpy as np
import pytest

from avoidance.geometric.config import GeometricConfig
from avoidance.geometric.conflict import detection_horizon, find_main_threat
from avoidance.geometric.planner import GeometricAvoider
from avoidance.geometric.threats import Threat, ThreatArrays
from sim.core.plan import Plan, Planner, PlanStatus, Threats
from sim.core.state import VehicleState
from sim.core.threats import IntruderTrack, SphereThreat

REF = np.array([[0.0, 0.0, -20.0], [50.0, 0.0, -20.0], [120.0, 0.0, -20.0]])  # north at 20 m


def state(t: float, north: float, east: float = 0.0, down: float = -20.0, speed: float = 5.0) -> VehicleState:
    return VehicleState(
        t=t,
        pos_ned=np.array([north, east, down]),
        vel_ned=np.array([speed, 0, 0]),
        euler=np.zeros(3),
        rates_body=np.zeros(3),
        alt_msl_m=-down,
        lat_deg=47.0,
        lon_deg=8.0,
    )


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
    assert np.allclose(p.positions[1], [12.5, 0, -20]) and p.times[1] == pytest.approx(2.5)  # latency shift
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
    assert av.still_valid(threats, 0.5, np.array([12.5, 0, -20]))
    # a new sphere right on the committed path's peak
    peak = first.positions[np.argmax(np.hypot(first.positions[:, 1], first.positions[:, 2] + 20))]
    blocked = Threats(spheres=[sphere(25.0), SphereThreat("new", 0.5, peak.copy(), 1.0)])
    assert not av.still_valid(blocked, 0.5, np.array([12.5, 0, -20]))
    re = av.plan(state(0.5, 12.5), blocked, 0.5)
    assert re.diagnostics["replan_reason"] == "invalid"
    assert re.status is PlanStatus.NO_SOLUTION or re.diagnostics["chosen_index"] != k


def test_no_solution_hovers_and_too_close_hovers():
    av = GeometricAvoider(REF, 5.0, GeometricConfig(start_shift_s=0.0))
    # a ring of spheres abreast of the main threat at 4.8 m, in the 8 directions of the planes:
    # every candidate peak (3.2 or 6.4 m off the reference) passes within 1.6 m of a centre
    ring = [
        SphereThreat(f"r{i}", 0.0, np.array([25.0, 4.8 * np.cos(a), -20 + 4.8 * np.sin(a)]), 2.0)
        for i, a in enumerate(np.radians(np.arange(0, 360, 45)))
    ]
    p = av.plan(state(3.0, 10.0), Threats(spheres=[sphere(25.0), *ring]), 3.0)
    assert p.status is PlanStatus.NO_SOLUTION and p.diagnostics["status"] == "no_solution"
    assert np.allclose(p.positions, [[10, 0, -20]]) and np.allclose(p.velocities, 0) and p.times[0] == 3.0
    p = av.plan(state(3.5, 10.0), Threats(spheres=[sphere(14.0)]), 3.5)
    assert p.status is PlanStatus.NO_SOLUTION and p.diagnostics["status"] == "too_close"


def test_intruder_track_with_covariance_and_candidate_log():
    cfg = GeometricConfig(start_shift_s=0.0, k_sigma=2.0)
    av = GeometricAvoider(REF, 5.0, cfg)
    head_on = IntruderTrack(
        "ac1",
        0.0,
        np.array([60.0, 0, -20]),
        np.array([-5.0, 0, 0]),
        1.0,
        pos_cov=np.eye(3) * 0.25,
        vel_cov=np.eye(3) * 0.01,
    )
    p = av.plan(state(0.0, 10.0), Threats(intruders=[head_on]), 0.0)
    assert p.diagnostics["main_threat_id"] == "ac1"
    assert p.diagnostics["t_cpa_s"] == pytest.approx(5.0)
    log = av.candidate_log()
    text = json.dumps(log)  # plain JSON
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
            state(0, 10), Threats(spheres=[sphere(30.0, center_cov=-np.eye(3))]), 0.0
        )
    assert isinstance(av.plan(state(0, 10), Threats(), 0.0), Plan)


# -- closed-loop rules ----------------------------------------------------------------------------
def peak_of(plan: Plan) -> tuple[np.ndarray, np.ndarray]:
    """The plan vertex farthest from the reference (the north axis at 20 m) and the unit NED
    direction of its offset."""
    off = plan.positions - np.array([1.0, 0, 0]) * plan.positions[:, :1] - [0, 0, -20.0]
    k = int(np.argmax(np.linalg.norm(off, axis=1)))
    return plan.positions[k].copy(), off[k] / np.linalg.norm(off[k])


def test_selection_needs_the_margin_the_committed_recheck_does_not():
    chosen_clearance = {}
    for margin in (0.0, 1.0):
        av = GeometricAvoider(REF, 5.0, GeometricConfig(start_shift_s=0.0, select_margin_m=margin))
        first = av.plan(state(0.0, 10.0), Threats(spheres=[sphere(25.0)]), 0.0)
        log = av.candidate_log()
        assert log["available"] == [c >= av.config.r_uav + margin for c in log["min_clearance_m"]]
        chosen_clearance[margin] = log["min_clearance_m"][log["chosen"]]
    r_uav = av.config.r_uav
    assert r_uav <= chosen_clearance[0.0] < r_uav + 1.0 <= chosen_clearance[1.0]
    # hysteresis: a sphere whose clearance to the committed path is inside the margin (but
    # outside r_uav) keeps the path; one inside r_uav drops it
    peak, out = peak_of(first)

    def near(gap: float) -> Threats:
        return Threats(spheres=[sphere(25.0), SphereThreat("near", 0.5, peak + out * (1.0 + gap), 1.0)])

    assert av.plan(state(0.5, 12.5), near(r_uav + 0.5), 0.5).diagnostics["status"] == "committed"
    assert not av.still_valid(near(r_uav - 0.1), 0.5, np.array([12.5, 0, -20]))


def test_static_threat_beyond_the_horizon_keeps_its_centre_and_radius():
    # the sphere's surface is within the 1 s look-ahead, its centre beyond it
    ta = ThreatArrays.of([Threat("s", np.array([6.5, 0, 0]), np.zeros(3), 2.0)])
    start, v = np.zeros(3), np.array([5.0, 0, 0])
    m = find_main_threat(start, v, ta, 1.0, 1.0, 20.0)
    assert m.t_cpa == pytest.approx(1.3) and np.allclose(m.p_c, [6.5, 0, 0])
    assert m.radius == pytest.approx(2.0) and m.miss == pytest.approx(0.0)
    cut = find_main_threat(start, v, ta, 1.0, 1.0)  # geometry cut at the horizon
    assert cut.t_cpa == pytest.approx(1.0) and cut.radius == pytest.approx(3.5)
    # the planner passes the time to the reference end: it plans around the sphere where it is
    # (with the cut geometry, dx = 5 m < 2.5 · 3.5 m would be "too close")
    av = GeometricAvoider(REF, 5.0, GeometricConfig(start_shift_s=0.0, conflict_horizon_s=1.0))
    p = av.plan(state(0.0, 10.0), Threats(spheres=[sphere(16.5)]), 0.0)
    assert p.diagnostics["status"] == "avoid" and p.diagnostics["t_cpa_s"] == pytest.approx(1.3)


def test_commitment_lasts_until_the_vehicle_passes_the_rejoin_point_not_the_schedule():
    av = GeometricAvoider(REF, 5.0, GeometricConfig(start_shift_s=0.0))
    threats = Threats(spheres=[sphere(25.0)])
    first = av.plan(state(0.0, 10.0), threats, 0.0)
    end = int(np.flatnonzero(first.labels == -1)[-1])  # the rejoin point
    peak, _ = peak_of(first)
    late = float(first.times[end]) + 2.0  # schedule over, vehicle at the peak
    lagging = av.plan(state(late, peak[0], peak[1], peak[2]), threats, late)
    assert lagging.diagnostics["status"] == "committed" and np.array_equal(lagging.positions, first.positions)
    past = av.plan(state(late + 0.1, first.positions[end, 0] + 0.2), threats, late + 0.1)
    assert past.diagnostics["status"] == "no_conflict"


def test_committed_recheck_is_retimed_to_the_vehicles_lag():
    av = GeometricAvoider(REF, 5.0, GeometricConfig(start_shift_s=0.0))
    first = av.plan(state(0.0, 10.0), Threats(spheres=[sphere(25.0)]), 0.0)
    path, times = first.positions[first.labels == -1], first.times[first.labels == -1]
    q = peak_of(first)[0]
    tq = float(times[np.flatnonzero(np.all(path == q, axis=1))[0]])
    v = np.array([0.0, 0.0, 5.0])  # descending through q at tq + 2 s

    def check(t: float, t_sched: float) -> bool:
        pos = np.array([np.interp(t_sched, times, path[:, i]) for i in range(3)])
        track = IntruderTrack("ac", t, q + v * (t - tq - 2.0), v, 1.0)
        return av.still_valid(Threats(spheres=[sphere(25.0)], intruders=[track]), t, pos)

    assert tq > 1.0
    assert check(1.0, 1.0)  # on schedule: at q 2 s before the intruder
    assert not check(3.0, 1.0)  # 2 s behind: at q with it


def test_hovering_vehicle_plans_from_where_it_is():
    threats = Threats(spheres=[sphere(25.0)])
    p = GeometricAvoider(REF, 5.0).plan(state(0.0, 19.5, speed=0.0), threats, 0.0)  # 0.75 s latency shift
    assert p.diagnostics["status"] == "avoid"
    assert np.allclose(p.positions[0], [19.5, 0, -20]) and p.times[0] == pytest.approx(0.75)
    # at cruise speed the evading point is 3.75 m ahead, 1.75 m from the centre
    moving = GeometricAvoider(REF, 5.0).plan(state(0.0, 19.5), threats, 0.0)
    assert moving.diagnostics["status"] == "too_close"


def test_replans_are_rate_limited_and_an_unsafe_commitment_hovers_meanwhile():
    threats = Threats(spheres=[sphere(25.0)])
    av = GeometricAvoider(REF, 5.0, GeometricConfig(start_shift_s=0.0))
    assert av.config.min_replan_interval_s == 0.5
    first = av.plan(state(0.0, 10.0), threats, 0.0)
    blocked = Threats(spheres=[sphere(25.0), SphereThreat("new", 0.2, peak_of(first)[0], 1.0)])
    p = av.plan(state(0.2, 11.0), blocked, 0.2)
    d = p.diagnostics
    assert p.status is PlanStatus.NO_SOLUTION and d["status"] == "rate_limited" and d["replan_reason"] == "invalid"
    assert np.allclose(p.positions, [[11, 0, -20]]) and np.allclose(p.velocities, 0) and "n_candidates" not in d
    assert av.plan(state(0.4, 11.5), blocked, 0.4).diagnostics["status"] == "rate_limited"
    assert av.plan(state(0.5, 11.6), blocked, 0.5).diagnostics["n_candidates"] == 32
    # without an interval the unsafe commitment is re-planned at once
    av0 = GeometricAvoider(REF, 5.0, GeometricConfig(start_shift_s=0.0, min_replan_interval_s=0.0))
    av0.plan(state(0.0, 10.0), threats, 0.0)
    again = av0.plan(state(0.2, 11.0), blocked, 0.2).diagnostics
    assert again["replan_reason"] == "invalid" and again["n_candidates"] == 32


def test_unsafe_commitment_far_off_the_reference_is_suspended_and_resumed():
    threats = Threats(spheres=[sphere(25.0)])
    av = GeometricAvoider(REF, 5.0, GeometricConfig(start_shift_s=0.0, select_margin_m=1.0))
    first = av.plan(state(0.0, 10.0), threats, 0.0)
    peak, out = peak_of(first)
    here = peak - np.array([2.0, 0, 0]) - out * 0.5  # before the peak, ~5.9 m off
    blocked = Threats(spheres=[sphere(25.0), SphereThreat("new", 2.0, peak, 1.0)])
    p = av.plan(state(2.0, *here), blocked, 2.0)
    assert p.status is PlanStatus.NO_SOLUTION and p.diagnostics["status"] == "suspended"
    assert np.allclose(p.positions, [here]) and p.diagnostics["cross_track_m"] > av.config.replan_max_offset_m
    resumed = av.plan(state(2.1, *here), threats, 2.1)
    assert resumed.diagnostics["status"] == "committed" and np.array_equal(resumed.positions, first.positions)


def test_unsafe_commitment_far_off_the_reference_flies_on_when_holding_is_worse():
    av = GeometricAvoider(REF, 5.0, GeometricConfig(start_shift_s=0.0, select_margin_m=1.0))
    first = av.plan(state(0.0, 10.0), Threats(spheres=[sphere(25.0)]), 0.0)
    peak, out = peak_of(first)
    here = peak - np.array([2.0, 0, 0]) - out * 0.5
    grazing = SphereThreat("new", 2.0, peak + out * 1.5, 1.0)  # 0.5 m from the path's peak
    from_above = IntruderTrack("ac", 2.0, here + [0, 0, -5.0], np.array([0, 0, 5.0]), 1.0)  # at `here` in 1 s
    p = av.plan(state(2.0, *here), Threats(spheres=[sphere(25.0), grazing], intruders=[from_above]), 2.0)
    d = p.diagnostics
    assert d["status"] == "committed_unsafe" and np.array_equal(p.positions, first.positions)
    assert d["clearance_hold_m"] < d["clearance_go_m"] < av.config.r_uav
    # the same path without the intruder: holding is clear, the vehicle hovers
    p = av.plan(state(2.1, *here), Threats(spheres=[sphere(25.0), grazing]), 2.1)
    assert p.diagnostics["status"] == "suspended" and p.diagnostics["clearance_hold_m"] >= av.config.r_uav


def test_avoidance_path_ending_past_the_last_waypoint_still_completes_the_mission():
    """A threat just before the last waypoint: the chosen path rejoins the line beyond its end.
    The plan must end at the last waypoint (labelled, so the follower can mark it reached) and the
    commitment must end once the vehicle is past the end of the reference (it used to stay
    'committed' for ever, the projection being clipped at the reference's length)."""
    ref = np.array([[0.0, 0.0, -20.0], [30.0, 0.0, -20.0]])
    av = GeometricAvoider(ref, 5.0, GeometricConfig(start_shift_s=0.5))
    p = av.plan(state(0.0, 18.0), Threats(spheres=[sphere(27.0)]), 0.0)
    assert p.diagnostics["status"] == "avoid"
    path_end = av._commit.points_enu[-1]
    assert path_end[1] > ref[-1, 0]  # ENU y = north: the rejoin point is past the last waypoint
    assert p.labels[-1] == 1 and np.allclose(p.positions[-1], ref[-1])
    beyond = av.plan(state(1.0, path_end[1], 0.0), Threats(spheres=[sphere(27.0)]), 3.0)
    assert beyond.diagnostics["status"] != "committed"
    assert beyond.labels[-1] == 1 and np.allclose(beyond.positions[-1], ref[-1])


def crossing(north: float) -> Threats:
    """An intruder (radius 1 m) flying east at 5 m/s across the reference at ``north`` [m],
    10 m west of it at t = 0: it crosses when a vehicle flying on from north 10 m is there."""
    return Threats(intruders=[IntruderTrack("x", 0.0, np.array([north, -10.0, -20.0]), np.array([0, 5.0, 0]))])


def test_too_close_conflict_flies_on_when_holding_is_worse_and_hovers_otherwise():
    # finding 8 of docs/encounters.md: a late conflict with a 5 m miss flown on becomes a 3 m
    # pass at a hovering vehicle. Protected radius 1 + 1.73 + 3.5 = 6.23 m, 2.5·R > 5 m/s · t_cpa.
    cfg = GeometricConfig(start_shift_s=0.0, uav_shape="sphere_circumscribed", select_margin_m=3.5)
    # crossing 3 m ahead: flying on misses by 4.95 m at t = 1.3 s, holding by 3 m
    p = GeometricAvoider(REF, 5.0, cfg).plan(state(0.0, 10.0), crossing(13.0), 0.0)
    d = p.diagnostics
    assert d["status"] == "too_close" and d["response"] == "fly_on" and p.status is PlanStatus.OK
    assert d["clearance_go_m"] == pytest.approx(4.95 - 1.0, abs=0.01) and d["clearance_hold_m"] == pytest.approx(2.0)
    assert np.allclose(p.positions[0], [10, 0, -20]) and np.allclose(p.positions[1:], REF[1:])
    # crossing 5.5 m ahead: flying on misses by 3.18 m, holding by 5.5 m: the vehicle hovers
    p = GeometricAvoider(REF, 5.0, cfg).plan(state(0.0, 10.0), crossing(15.5), 0.0)
    d = p.diagnostics
    assert d["status"] == "too_close" and d["response"] == "hover" and p.status is PlanStatus.NO_SOLUTION
    assert d["clearance_hold_m"] == pytest.approx(4.5) and d["clearance_go_m"] < d["clearance_hold_m"]
    assert np.allclose(p.positions, [[10, 0, -20]])


def test_min_height_keeps_candidates_above_the_floor():
    # finding 9 of docs/encounters.md: a candidate 21.9 m down from 20 m flew the ownship into the
    # ground. At 20 m with a 6 m floor no chosen or available candidate goes below 6 m.
    threats = Threats(spheres=[sphere(40.0, r=5.0)])
    free = GeometricAvoider(REF, 5.0, GeometricConfig(start_shift_s=0.0, path_types=("symmetric",)))
    free.plan(state(0.0, 10.0), threats, 0.0)
    floored = GeometricAvoider(
        REF, 5.0, GeometricConfig(start_shift_s=0.0, path_types=("symmetric",), min_height_m=6.0)
    )
    p = floored.plan(state(0.0, 10.0), threats, 0.0)

    def available_below_floor(av: GeometricAvoider) -> np.ndarray:
        log = av.candidate_log()
        assert log is not None
        return (np.asarray(log["points_ned"])[:, :, 2].max(axis=1) > -6.0) & np.asarray(log["available"])

    assert available_below_floor(free).any()  # without the floor some available candidate dips below 6 m
    assert not available_below_floor(floored).any()
    assert p.diagnostics["status"] == "avoid" and (-p.positions[:, 2]).min() >= 6.0
    with pytest.raises(ValueError, match="min_height_m"):
        GeometricConfig(min_height_m=float("nan"))


def test_own_position_uncertainty_grows_every_threat_by_k_sigma_own():
    """A sphere 0.5 m outside the body clearance of the reference is no conflict; an estimate
    with a 0.6 m largest 1-sigma axis and ``k_sigma_own = 1`` grows it into one. Without that
    option, or an estimate without uncertainty, nothing changes. The committed path's re-check
    keeps the allowance: a sphere 0.5 m outside the body clearance of the path drops it."""
    sigma = np.array([0.3, 0.6, 0.2])

    def first_plan(k_own: float, with_sigma: bool) -> tuple[GeometricAvoider, Plan]:
        cfg = GeometricConfig(start_shift_s=0.0, k_sigma_own=k_own, conflict_horizon_s=8.0)
        av = GeometricAvoider(REF, 5.0, cfg)
        est = state(0.0, 10.0)
        if with_sigma:
            est.pos_sigma_m = sigma
        side = Threats(spheres=[sphere(40.0, east=av.config.r_uav + 2.0 + 0.5)])
        return av, av.plan(est, side, 0.0)

    assert first_plan(0.0, True)[1].diagnostics["status"] == "no_conflict"
    assert first_plan(1.0, False)[1].diagnostics["status"] == "no_conflict"
    av, p = first_plan(1.0, True)
    assert p.diagnostics["status"] == "avoid"
    assert av.own_allowance(state(0.0, 0.0)) == 0.0

    av = GeometricAvoider(REF, 5.0, GeometricConfig(start_shift_s=0.0, k_sigma_own=1.0))
    first = av.plan(state(0.0, 10.0), Threats(spheres=[sphere(25.0)]), 0.0)
    peak, out = peak_of(first)
    near = Threats(spheres=[sphere(25.0), SphereThreat("near", 0.5, peak + out * (1.0 + av.config.r_uav + 0.5), 1.0)])
    assert av.plan(state(0.5, 12.5), near, 0.5).diagnostics["status"] == "committed"
    uncertain = state(0.5, 12.5)
    uncertain.pos_sigma_m = sigma
    assert av.plan(uncertain, near, 0.5).diagnostics["status"] != "committed"


def test_detection_horizon_by_hand():
    # r = 1 m threats, r_uav + margin 5.232 m (conflict within T = 6.232 m), 2.5 R rule, 5 m/s,
    # 0.5 s lead. Missing by 6 m closing at 10 m/s: R = 7 m, 2.5 · 7 / 5 + 0.5 = 4.0 s, less the
    # sqrt(6.232² − 6²) / 10 = 0.1685 s by which the clipped miss sees it early: 3.831 s. On the
    # line, static (closing at 5 m/s), growing at 0.5 m/s: 2.5 · 1 / 5 + 0.5 − 6.232 / 5 = −0.246 s
    # (the plain conflict_horizon_s applies). Missing by 7 m, no conflict: 2.5 · 8 / 5 + 0.5 = 4.5 s.
    ta = ThreatArrays.of([Threat(f"t{g}", np.zeros(3), np.zeros(3), 1.0, g) for g in (0.0, 0.5, 0.0)])
    h = detection_horizon(np.array([6.0, 0.0, 7.0]), np.array([10.0, 5.0, 10.0]), ta, 5.232, 2.5, 5.0, 0.5)
    assert h == pytest.approx([4.0 - 0.16846, 1.0 - 6.232 / 5.0, 4.5], abs=1e-4)


def test_a_conflict_is_first_seen_while_candidates_can_still_be_built():
    # finding 14 of docs/encounters.md: a head-on intruder (r = 1 m) at 5 m/s missing by 6 m, inside
    # the protected 1 + 1.732 + 3.5 = 6.232 m. Its enclosing radius is 1 + 6 = 7 m, too close below
    # 2.5 · 7 = 17.5 m = 3.5 s along the reference: with a 3 s horizon the first conflict is too
    # close. The look-ahead stretches to 3.831 s for it (test above): the miss at that horizon is
    # below 6.232 m from t_cpa = 4.0 s on, so at 10 Hz (t_cpa = 6.0, 5.9, ...) it is first seen at
    # t_cpa = 4.0 s (or 3.9 s, rounding), where the evading point is 20 m >= 17.5 m + 0.5 s from the
    # collision point, and candidates are built.
    cfg = GeometricConfig(
        start_shift_s=0.0, uav_shape="sphere_circumscribed", select_margin_m=3.5, conflict_horizon_s=3.0
    )
    av = GeometricAvoider(REF, 5.0, cfg)
    for k in range(60):
        t = 0.1 * k
        north = 10.0 + 5.0 * t
        track = IntruderTrack("x", t, np.array([north + 60.0 - 10.0 * t, 6.0, -20.0]), np.array([-5.0, 0, 0]), 1.0)
        d = av.plan(state(t, north), Threats(intruders=[track]), t).diagnostics
        if d["status"] != "no_conflict":
            break
    assert d["status"] == "avoid" and d["n_candidates"] > 0 and d["horizon_s"] == pytest.approx(3.831, abs=1e-3)
    assert 3.85 < d["t_cpa_s"] < 4.05
