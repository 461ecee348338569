"""Electrical energy of a solar aircraft: sun and irradiance at the vehicle (pvlib), solar-array
power from the wing's attitude, battery state of charge, loads and propulsion power.

- :mod:`sim.energy.params`: the airframe's ``energy.toml`` (array, battery, loads, atmosphere)
- :mod:`sim.energy.solar`: sun position and clear-sky irradiance at position, time and altitude
- :mod:`sim.energy.battery`: state of charge with charge/discharge efficiencies and limits
- :mod:`sim.energy.power_system`: the bus of one vehicle, its log record and depletion
"""
