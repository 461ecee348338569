"""The loop closes on estimates: faults, wind, and proof that nothing flies on truth."""

import dataclasses

import numpy as np
import pytest

from sim.core.frames import euler_to_dcm
from sim.estimator import PerfectEstimator
from sim.replay.report import log_metrics
from sim.replay.runlog import RunLog

pytestmark = pytest.mark.closed_loop


@pytest.fixture
def hover(scenario_data):
    """``hover(duration)``: the quadrotor holding its hover point level on the default estimator
    (sensors + EKF) for ``duration`` [s]."""

    def make(duration: float) -> dict:
        data = scenario_data("quad_hover_offset")
        data.update(duration=duration, stop_when_complete=False)
        v = data["vehicle"][0]
        v.pop("estimator")  # the default: sensors + EKF
        v["initial"].update(roll=0, pitch=0)
        v["mission"]["waypoints"][0]["hold"] = "600 s"
        return data

    return make


def test_gnss_loss_degrades_gracefully_and_recovers(fly, hover):
    data = hover(80.0)
    data["fault"] = [{"vehicle": "quad", "kind": "gnss_loss", "at": 30.0, "duration": 20.0}]
    data["logging"] = {"rate_hz": 10}
    run = fly(data)
    assert run.result.status in ("completed", "duration_elapsed")
    log = run.log
    sig = log.topic("/quad/est/sigma3")
    horiz = np.asarray(sig["pos"])[:, 0]
    t = sig.t
    before, during_end, after = horiz[t == 29.0][0], horiz[(t > 49.0) & (t < 50.0)].max(), horiz[t == 70.0][0]
    assert during_end > 2.0 * before  # the covariance grows while blind
    assert after < 1.5 * before  # and shrinks back once the fix returns
    truth = log.topic("/quad/truth/state")["pos_ned"]
    assert np.abs(truth[:, :2] - truth[0, :2]).max() < 10.0  # still controlled, near its hold point
    events = [e for _, e in log.events() if "gnss_loss" in e]
    assert events == ["quad: fault gnss_loss: started", "quad: fault gnss_loss: ended"]


def _mean_air_wind(log: RunLog, name: str) -> np.ndarray:
    """Mean of ground velocity - air velocity over the run, NED [m/s] (the wind it flew in)."""
    tr = log.topic(f"/{name}/truth/state")
    a, b, v = (np.asarray(tr[k]) for k in ("alpha_rad", "beta_rad", "tas_mps"))
    body = np.column_stack([v * np.cos(a) * np.cos(b), v * np.sin(b), v * np.sin(a) * np.cos(b)])
    air = np.array([euler_to_dcm(*e) @ u for e, u in zip(np.asarray(tr["euler"]), body, strict=True)])
    return (np.asarray(tr["vel_ned"]) - air).mean(axis=0)


def test_haps_mission_in_wind_and_turbulence(fly, scenario_data):
    data = scenario_data("mixed_haps_quad")
    data["vehicle"] = data["vehicle"][:1]  # the HAPS and its 4 km box
    data["wind"] = {"north": "-7.07 m/s", "east": "7.07 m/s", "turbulence": "moderate"}
    run = fly(data)
    assert run.result.status == "completed"
    # it flew in the wind (mean -7.14, 7.16 m/s over the run: the turbulence averages out) ...
    assert _mean_air_wind(run.log, "haps")[:2] == pytest.approx([-7.07, 7.07], abs=0.5)
    tr = log_metrics(run.log)["vehicles"]["haps"]["tracking"]
    # ... and held its box: cross-track max 2.0 m, altitude max 4.3 m, airspeed rms 0.35 m/s;
    # turbulence moves the airspeed by a few m/s at once, the autopilot holds it on average
    assert tr["cross_track_m"]["max_abs"] <= 10.0
    assert tr["altitude_error_m"]["max_abs"] <= 50.0 and tr["airspeed_error_mps"]["rms"] <= 1.5


def test_multirotor_mission_in_wind(fly, scenario_data):
    data = scenario_data("quad_square_mission")
    data["wind"] = {"north": "3 m/s", "east": "4 m/s", "turbulence": "light"}
    run = fly(data)
    assert run.result.status == "completed"
    assert _mean_air_wind(run.log, "quad")[:2] == pytest.approx([3.0, 4.0], abs=1.0)  # 2.2, 4.2 m/s
    # on the EKF in 5 m/s: cross-track max 2.8 m, rms 1.18 m; over 20 seeds max 3.8 m (docs/environment.md)
    assert log_metrics(run.log)["vehicles"]["quad"]["tracking"]["cross_track_m"]["max_abs"] <= 4.0


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(20))
def test_multirotor_mission_in_wind_across_seeds(fly, scenario_data, seed):
    """The square mission in the same wind on seeds 0-19: it completes and keeps its track
    (measured: cross-track max median 1.96 m, worst 3.80 m). The mean air-relative wind of one
    70 s flight in light turbulence spreads by up to 1.8 m/s between seeds, so the shipped seed's
    wind check is not repeated here."""
    data = scenario_data("quad_square_mission")
    data["wind"] = {"north": "3 m/s", "east": "4 m/s", "turbulence": "light"}
    data["seed"] = seed
    run = fly(data, f"wind{seed}")
    assert run.result.status == "completed"
    assert log_metrics(run.log)["vehicles"]["quad"]["tracking"]["cross_track_m"]["max_abs"] <= 4.0


class _OffsetEstimator(PerfectEstimator):
    """Ideal sensors but a deliberate 5 m north error in the position estimate."""

    name = "offset"

    def update(self, t):
        s = super().update(t)
        return dataclasses.replace(s, pos_ned=s.pos_ned + np.array([5.0, 0.0, 0.0]))


def test_controllers_and_planners_follow_the_estimate_not_the_truth(fly, hover, monkeypatch):
    monkeypatch.setattr(
        "sim.vehicle.make_estimator", lambda kind, plant, airframe, seed, origin, sensors: _OffsetEstimator(plant)
    )
    log = fly(hover(20.0)).log
    truth = log.topic("/quad/truth/state")["pos_ned"]
    est = log.topic("/quad/est/state")["pos_ned"]
    # the vehicle holds its ESTIMATE on the hold point, so in truth it sits 5 m south of it
    assert est[-1, 0] == pytest.approx(0.0, abs=0.2)
    assert truth[-1, 0] == pytest.approx(-5.0, abs=0.2)


def test_lidar_in_the_loop_sees_the_map_obstacle(fly, hover):
    data = hover(2.0)
    data["vehicle"][0]["lidar"] = {"rate_hz": 5}
    data["obstacle"] = [
        {"id": "wall", "shape": "box", "north": 6.0, "east": 0.0, "length": 2.0, "width": 20.0, "top": 440.0}
    ]
    hits = [m["lidar_hits"] for m in fly(data).log.topic("/quad/threats").messages]
    assert min(hits) > 1000  # every plan saw the wall (the sweep runs before planning)
    data["obstacle"] = []
    assert max(m["lidar_hits"] for m in fly(data, "empty").log.topic("/quad/threats").messages) == 0
