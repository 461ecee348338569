"""Closed loop: the JSBSim quadrotor flying on its EKF estimate with the geometric avoider through
the thesis encounters (scenarios/geometric/*.toml), judged on the truth in the MCAP.

Clearance criterion (spec G10, §4.3): the 2 m vehicle box must stay clear of every threat
sphere; the box is within its circumscribed sphere of radius √3 m, so the check is
``|p_vehicle - p_object| - R_object > √3`` on the true positions, evaluated exactly between the
10 Hz log samples (both move linearly over a sample interval).
"""

from __future__ import annotations

import numpy as np
import pytest

from sim.replay.runlog import RunLog

BOX_HALF_DIAGONAL = np.sqrt(3.0)  # 2 m cube
pytestmark = pytest.mark.closed_loop


def clearances(log: RunLog, vehicle: str = "quad") -> dict[str, tuple[float, float]]:
    """Per object: (min over the run of |p_vehicle - p_object| - R [m], time of it [s]), true
    positions, exact minimum of the linearly interpolated relative motion between samples."""
    st = log.topic(f"/{vehicle}/truth/state")
    objs = log.topic("/world/objects")
    t = st.t
    out: dict[str, tuple[float, float]] = {}
    ids = sorted({o["id"] for m in objs.messages for o in m["objects"]})
    for oid in ids:
        pts, radius = [], None
        for m in objs.messages:
            o = next((o for o in m["objects"] if o["id"] == oid), None)
            pts.append(o["pos_ned"] if o else [np.nan] * 3)
            radius = o["radius_m"] if o else radius
        p_obj = np.array([np.interp(t, objs.t, np.asarray(pts)[:, i]) for i in range(3)]).T
        rel = st["pos_ned"] - p_obj
        a, b = rel[:-1], rel[1:]
        d = b - a
        dd = np.einsum("ij,ij->i", d, d)
        u = np.clip(-np.einsum("ij,ij->i", a, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
        dist = np.linalg.norm(a + d * u[:, None], axis=1)
        ok = np.isfinite(dist)
        k = int(np.nanargmin(np.where(ok, dist, np.nan)))
        out[oid] = (float(dist[k] - radius), float(t[k] + u[k] * (t[k + 1] - t[k])))
    return out


def avoidance_events(log: RunLog, vehicle: str = "quad") -> list[dict]:
    """The planning events with candidates (first one first) as logged on /<v>/plan/candidates."""
    if not log.has(f"/{vehicle}/plan/candidates"):
        return []
    return list(log.topic(f"/{vehicle}/plan/candidates").messages)


def chosen(ev: dict) -> dict:
    k = ev["chosen"]
    n = ev["n_pts"][k]
    pts = np.asarray(ev["points_ned"][k][:n])
    return {
        "theta": ev["theta_deg"][k],
        "alpha": ev["alpha_deg"][k],
        "omega": ev["omega_m"][k],
        "type": ev["path_type"][k],
        "cost": ev["cost"][k],
        "points": pts,
    }


def assert_clear_and_complete(run) -> dict[str, tuple[float, float]]:
    """Clear of every object (clearance per object returned), and the mission completed."""
    log = run.log
    cl = clearances(log)
    assert cl, "no objects logged"
    for oid, (c, t) in cl.items():
        assert c > BOX_HALF_DIAGONAL, f"{oid}: clearance {c:.2f} m at t = {t:.1f} s"
    events = [text for _, text in log.events()]
    assert "quad: mission complete" in events
    assert run.result.status == "completed"
    return cl


def first_avoid(log: RunLog) -> dict:
    evs = [e for e in avoidance_events(log) if e["status"] == "avoid"]
    assert evs, "the avoider never chose a path"
    return evs[0]


def test_s1_160_solution_in_the_horizontal_plane_wider_for_the_larger_threat(fly):
    widths = {}
    for name, radius in (("s1_160_r1", 1.0), ("s1_160_r1p5", 1.5)):
        run = fly(f"geometric/{name}")
        assert_clear_and_complete(run)
        log = run.log
        c = chosen(first_avoid(log))
        assert c["alpha"] == pytest.approx(0.0, abs=1e-6)  # horizontal plane
        widths[radius] = abs(c["omega"])
    assert widths[1.5] > widths[1.0]


def test_s2_climbs_over(fly):
    run = fly("geometric/s2_climb_over")
    assert_clear_and_complete(run)
    log = run.log
    ev = first_avoid(log)
    c = chosen(ev)
    assert ev["main_threat_id"] == "main" and c["theta"] == pytest.approx(90.0)
    # the vehicle climbs faster than the 20° reference (5 sin 20° = 1.71 m/s) while avoiding
    st = log.topic("/quad/truth/state")
    during = (st.t >= ev["t"]) & (st.t <= ev["t"] + 4.0)
    assert (-chosen(ev)["points"][:, 2]).max() > -chosen(ev)["points"][0, 2] + 3.0  # planned above
    assert (-st["vel_ned"][during, 2]).max() > 5.0 * np.sin(np.radians(20.0)) + 0.25


def test_s3_static_descends_first_moving_goes_left_and_costs_more(fly):
    run = fly("geometric/s3a_static_main")
    assert_clear_and_complete(run)
    log = run.log
    ev = first_avoid(log)
    static = chosen(ev)
    pts = static["points"]
    mid = pts[len(pts) // 2]
    assert -(mid[2] - pts[0][2]) < -1.0  # below the reference at the peak
    st = log.topic("/quad/truth/state")
    h = -(st["pos_ned"][:, 2] - st["pos_ned"][0, 2])
    during = (st.t >= ev["t"]) & (st.t <= ev["t"] + 4.0)
    assert h[during].min() < -1.0 and h[during].max() < 0.5
    # moving main threat: a level path to the left (west of the northbound reference), costlier
    run = fly("geometric/s3b_moving_main")
    assert_clear_and_complete(run)
    log = run.log
    ev = first_avoid(log)
    moving = chosen(ev)
    assert ev["main_threat_id"] == "main" and moving["alpha"] == pytest.approx(0.0, abs=1e-6)
    off = moving["points"] - moving["points"][0]
    assert np.abs(off[:, 2]).max() < 1e-6 and off[:, 1].min() < -3.0 and off[:, 1].max() < 1e-6
    assert moving["cost"] > static["cost"]


@pytest.mark.parametrize("name", ["s1_174_r1p5", "env1_tuning", "env2_tuning", "env3_tuning", "env4_tuning"])
def test_more_encounters_stay_clear_and_complete(fly, name):
    run = fly(f"geometric/{name}")
    assert_clear_and_complete(run)
    log = run.log
    assert first_avoid(log)["main_threat_id"] == "main"
