"""Every tunable loop of both airframes: its gains, its transfer functions and its JSBSim step.

A :class:`Loop` is opened where all of its gains act, so multiplying those gains by one factor
multiplies its open loop L by the same factor (what :mod:`sim.tuning.tuner` solves for). Cascades
are built from the inside out with the inner loops closed at the gains given.

=========  =====================  ==============================  =========================
airframe   loop                   gains (``gains.toml`` keys)     opened at
=========  =====================  ==============================  =========================
haps       roll                   inner.kp/ki/kd_roll             aileron command
haps       pitch                  inner.kp/ki/kd_pitch            elevator command
haps       tecs-pitch             (not a single-factor loop)      pitch command
haps       tecs-throttle          (not a single-factor loop)      throttle
quadrotor  rate (roll)            rate.roll.kp/ki/kd              roll-torque command
quadrotor  attitude (roll)        attitude.kp_roll                roll-rate command
quadrotor  velocity (horizontal)  velocity.kp/ki/kd_xy            acceleration demand
quadrotor  position (horizontal)  position.kp_xy                  velocity demand
quadrotor  yaw-rate               rate.yaw.kp/ki/kd               yaw-torque command
quadrotor  yaw                    attitude.kp_yaw                 yaw-rate command
quadrotor  climb-rate             velocity.kp/ki/kd_z             vertical acceleration demand
quadrotor  altitude               position.kp_z                   climb-rate demand
=========  =====================  ==============================  =========================

Gains are addressed by their dataclass field path (``kp_roll`` on :class:`HapsGains`,
``rate.roll.kp`` on :class:`MultirotorGains`); :func:`file_key` gives the ``gains.toml`` key.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from aircraft.haps.gains import HapsGains
from aircraft.quadrotor.gains import MultirotorGains
from sim.tuning import steps
from sim.tuning.loops import LoopReport, StepResponse, analyse

AIRFRAME_LOOPS = {
    "haps": ("roll", "pitch", "tecs-pitch", "tecs-throttle"),
    "quadrotor": ("rate", "attitude", "velocity", "position", "yaw-rate", "yaw", "climb-rate", "altitude"),
}
HAPS_STEP = {"roll": math.radians(5.0), "pitch": math.radians(2.0)}  # [rad]
TECS_STEP_M, TECS_RATE_MPS = 2.0, 0.5  # altitude setpoint ramp of the TECS step


def tecs_drive(t: np.ndarray) -> np.ndarray:
    """[h_ref, h_ref_rate] of the TECS step, per metre of the final change."""
    ramp_s = TECS_STEP_M / TECS_RATE_MPS
    return np.vstack([np.clip(t / ramp_s, 0.0, 1.0), np.where(t < ramp_s, 1.0 / ramp_s, 0.0)])


@dataclass(frozen=True)
class Loop:
    """One loop: ``build(gains) -> (L, T)`` (open loop at ``opened_at``, closed loop from its
    command to its output), ``fly(gains, seconds)`` its JSBSim step, ``gains`` the field paths
    scaled together, ``unit`` of its command and output, ``sample_hz`` its update rate,
    ``record_s`` the step's length (beyond its settling time at the shipped gains)."""

    airframe: str
    name: str
    opened_at: str
    unit: str
    gains: tuple[str, ...]
    build: Callable[[Any], tuple[Any, Any]]
    fly: Callable[[Any, float], StepResponse]
    sample_hz: float
    record_s: float
    drive: Callable[[np.ndarray], np.ndarray] | None = None  # T's inputs for a unit change; None: unit step

    @property
    def tunable(self) -> bool:
        """Whether scaling ``gains`` scales the open loop (false for the TECS loops)."""
        return bool(self.gains)

    def step(self, gains: Any) -> StepResponse:
        """The JSBSim step with ``gains`` over ``record_s``."""
        return self.fly(gains, self.record_s)

    def analyse(self, gains: Any) -> LoopReport:
        """Margins and linear step figures with ``gains`` (same record as :meth:`step`)."""
        return analyse(f"{self.airframe} {self.name}", *self.build(gains), self.record_s, self.drive)

    @property
    def max_crossover_rad_s(self) -> float:
        """A tenth of the sample frequency [rad/s]: beyond it the half-step delay no longer
        stands for the zero-order hold."""
        return 2 * math.pi * self.sample_hz / 10.0


def gain_value(gains: Any, path: str) -> float:
    """The gain at dotted field ``path``."""
    obj = gains
    for part in path.split("."):
        obj = getattr(obj, part)
    return float(obj)


def with_gains(gains: Any, values: dict[str, float]) -> Any:
    """A copy of the (frozen, nested) gains with the dotted field paths set to ``values``."""
    for path, v in values.items():
        head, _, rest = path.partition(".")
        gains = replace(gains, **{head: with_gains(getattr(gains, head), {rest: v}) if rest else v})
    return gains


def scaled(gains: Any, paths: tuple[str, ...], factor: float) -> Any:
    """The gains with those at ``paths`` multiplied by ``factor``."""
    return with_gains(gains, {p: factor * gain_value(gains, p) for p in paths})


def file_key(airframe: str, path: str) -> str:
    """``section.key`` of a gain in the airframe's ``gains.toml``."""
    if airframe == "haps":
        section = {f.name: f.metadata["section"] for f in fields(HapsGains)}[path]
        return f"{section}.{path}"
    return path


def default_gains(airframe: str) -> Any:
    return HapsGains.load() if airframe == "haps" else MultirotorGains.load()


def haps_loops(alt_m: float = 20_000.0, tas_mps: float = 29.7) -> list[Loop]:
    """The HAPS roll and pitch holds at a JSBSim trim (``alt_m`` MSL, ``tas_mps`` TAS)."""
    from sim.tuning.evaluator import JSBSimEvaluator
    from sim.tuning.linearize import linearize
    from sim.tuning.loops_haps import HapsTrimContext, haps_pitch_loops, haps_roll_loops
    from sim.tuning.loops_tecs import tecs_loops, thrust_lag
    from sim.tuning.trim_haps import jsbsim_trim

    pt, plant = jsbsim_trim(alt_m, tas_mps)
    if plant is None:
        raise ValueError(f"HAPS does not trim at {alt_m:.0f} m, {tas_mps:.1f} m/s: {pt.reason}")
    ctx = HapsTrimContext.of(plant, HapsGains.load())
    lm = linearize(JSBSimEvaluator(plant))
    lag = thrust_lag(plant)

    def tecs(channel: int) -> Callable[[HapsGains], tuple[Any, Any]]:
        def build(g: HapsGains) -> tuple[Any, Any]:
            loops = tecs_loops(lm, lag, g, ctx)
            return loops[channel], loops[2]

        return build

    def tecs_fly(g: HapsGains, seconds: float) -> StepResponse:
        return steps.haps_tecs_step(g, seconds, TECS_STEP_M, TECS_RATE_MPS, alt_m, tas_mps)

    def pitch(g: HapsGains):
        l_el, _, t = haps_pitch_loops(lm, g, ctx)
        return l_el, t

    def step(axis: str) -> Callable[[HapsGains, float], StepResponse]:
        return lambda g, s: steps.haps_attitude_step(axis, g, HAPS_STEP[axis], s, alt_m, tas_mps)

    return [
        Loop(
            "haps",
            "roll",
            "aileron command",
            "rad",
            ("kp_roll", "ki_roll", "kd_roll"),
            lambda g: haps_roll_loops(lm, g, ctx),
            step("roll"),
            120.0,
            10.0,
        ),
        Loop(
            "haps",
            "pitch",
            "elevator command",
            "rad",
            ("kp_pitch", "ki_pitch", "kd_pitch"),
            pitch,
            step("pitch"),
            120.0,
            30.0,
        ),
        Loop("haps", "tecs-pitch", "pitch command", "m", (), tecs(0), tecs_fly, 10.0, 80.0, tecs_drive),
        Loop("haps", "tecs-throttle", "throttle", "m", (), tecs(1), tecs_fly, 10.0, 80.0, tecs_drive),
    ]


def quad_loops() -> list[Loop]:
    """The quadrotor's roll-axis rate and attitude loops, its horizontal velocity and position
    loops (east), its yaw-rate and yaw loops and its vertical climb-rate and altitude loops (up),
    on the roll, yaw and collective plants identified in JSBSim at hover."""
    from sim.tuning.loops_quad import identify_rotor_axis, quad_loops, quad_vertical_loops, quad_yaw_loops

    roll, yaw, collective = (identify_rotor_axis(a) for a in ("roll", "yaw", "collective"))
    build: dict[str, Callable[[MultirotorGains], tuple[Any, Any]]] = {
        "rate": lambda g: quad_loops(roll, g).rate,
        "attitude": lambda g: quad_loops(roll, g).attitude,
        "velocity": lambda g: quad_loops(roll, g).velocity,
        "position": lambda g: quad_loops(roll, g).position,
        "yaw-rate": lambda g: quad_yaw_loops(yaw, g)[0],
        "yaw": lambda g: quad_yaw_loops(yaw, g)[1],
        "climb-rate": lambda g: quad_vertical_loops(collective, g)[0],
        "altitude": lambda g: quad_vertical_loops(collective, g)[1],
    }

    def pid(prefix: str, suffix: str = "") -> tuple[str, ...]:
        return tuple(f"{prefix}k{t}{suffix}" for t in "pid")

    spec = (
        ("rate", "roll-torque command", "rad/s", pid("rate.roll."), steps.quad_rate_step, 240.0, 2.0),
        ("attitude", "roll-rate command", "rad", ("attitude.kp_roll",), steps.quad_attitude_step, 240.0, 1.5),
        ("velocity", "acceleration demand", "m/s", pid("velocity.", "_xy"), steps.quad_velocity_step, 60.0, 12.0),
        ("position", "velocity demand", "m", ("position.kp_xy",), steps.quad_position_step, 60.0, 10.0),
        ("yaw-rate", "yaw-torque command", "rad/s", pid("rate.yaw."), steps.quad_yaw_rate_step, 240.0, 5.0),
        ("yaw", "yaw-rate command", "rad", ("attitude.kp_yaw",), steps.quad_yaw_step, 240.0, 3.0),
        ("climb-rate", "up acceleration demand", "m/s", pid("velocity.", "_z"), steps.quad_climb_rate_step, 60.0, 6.0),
        ("altitude", "climb-rate demand", "m", ("position.kp_z",), steps.quad_altitude_step, 60.0, 8.0),
    )
    return [Loop("quadrotor", n, at, unit, paths, build[n], fn, hz, rec) for n, at, unit, paths, fn, hz, rec in spec]


def loops_of(airframe: str, alt_m: float = 20_000.0, tas_mps: float = 29.7) -> list[Loop]:
    """Every loop of ``airframe`` (``haps`` at the given trim point)."""
    if airframe == "haps":
        return haps_loops(alt_m, tas_mps)
    if airframe == "quadrotor":
        return quad_loops()
    raise ValueError(f"unknown airframe {airframe!r} (known: {', '.join(AIRFRAME_LOOPS)})")
