"""The plant's fast property access: ``JSBSimPlant.kinematics`` (the contact checks' read) gives
exactly ``truth()``'s position and velocity, whether or not the full truth of that sim time was
read first; ``set_many`` (cached setters) writes as setting each property by name does."""

from __future__ import annotations

import numpy as np

from aircraft import airframe_dir
from sim.geodesy import GeoPoint
from sim.jsbsim_plant import InitialConditions, JSBSimPlant

ORIGIN = GeoPoint(47.0, 8.0, 400.0)


def test_kinematics_are_the_truths_position_and_velocity():
    plant = JSBSimPlant("quadrotor", 1.0 / 240.0, ORIGIN, airframe_dir("quadrotor"))
    plant.initialise(InitialConditions(GeoPoint(47.02, 8.03, 900.0), tas_mps=12.0, heading_rad=0.7))
    for _ in range(5):
        plant.step(37)
        pos, vel = plant.kinematics()  # before any truth read at this time: the property reads
        truth = plant.truth()
        assert np.array_equal(pos, truth.pos_ned) and np.array_equal(vel, truth.vel_ned)
        assert abs(truth.pos_ned[0]) > 2000.0 and np.linalg.norm(truth.vel_ned) > 5.0  # away, moving
        again = plant.kinematics()  # after it: the truth's own arrays
        assert again[0] is truth.pos_ned and again[1] is truth.vel_ned


def test_set_many_writes_and_creates_like_setting_by_name():
    plant = JSBSimPlant("quadrotor", 1.0 / 240.0, ORIGIN, airframe_dir("quadrotor"))
    plant.initialise(InitialConditions(GeoPoint(47.0, 8.0, 500.0)))
    for k, throttle in enumerate((0.4, 0.7)):  # the second write goes through the cached setters
        plant.set_many({"fcs/throttle-cmd-norm[1]": throttle, "ap/not-in-the-model": float(k + 3)})
        assert plant["fcs/throttle-cmd-norm[1]"] == throttle
        assert plant["ap/not-in-the-model"] == k + 3
        assert plant.fdm.get_property_value("ap/not-in-the-model") == k + 3
