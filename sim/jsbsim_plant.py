"""One JSBSim FGFDMExec per vehicle: loading, initial conditions, trim, stepping, properties.

Truth state comes out as a :class:`sim.core.state.VehicleState` in the scenario's NED frame [m, m/s,
rad]. JSBSim's own units (ft, kt, slug) stay inside this module and ``sim.core.constants``.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import jsbsim
import numpy as np

from sim.core.constants import FT, KT
from sim.core.frames import euler_to_dcm
from sim.core.state import VehicleState
from sim.geodesy import GeoPoint, LocalLevelFrame


class PlantError(RuntimeError):
    """A JSBSim model could not be loaded, initialised, trimmed or stepped."""


class _QuietLogger(jsbsim.FGLogger):
    """Keeps JSBSim's console quiet; remembers recent warnings and errors for our messages."""

    def __init__(self) -> None:
        super().__init__()
        self.recent: deque[str] = deque(maxlen=20)
        self._level = jsbsim.LogLevel.BULK
        self._parts: list[str] = []

    def set_level(self, level) -> None:
        self._level = level
        self._parts = []

    def file_location(self, filename: str, line: int) -> None:
        self._parts.append(f"{filename}:{line}: ")

    def message(self, message: str) -> None:
        self._parts.append(message)

    def format(self, format) -> None:
        pass

    def flush(self) -> None:
        if self._level >= jsbsim.LogLevel.WARN and self._parts:
            self.recent.append("".join(self._parts).strip())
        self._parts = []


_local = threading.local()


def _quiet_logger() -> _QuietLogger:
    """The thread's quiet logger (JSBSim loggers are per thread)."""
    logger = getattr(_local, "logger", None)
    if logger is None:
        logger = _local.logger = _QuietLogger()
        jsbsim.set_logger(logger)
    return logger


@dataclass(frozen=True, slots=True)
class InitialConditions:
    """Initial state: position (WGS84), true airspeed [m/s], heading [rad], attitude [rad];
    ``terrain_alt_m``: elevation of the (flat) ground, MSL [m]. ``on_ground`` puts the vehicle
    on it, whatever ``position.alt_m`` says."""

    position: GeoPoint
    tas_mps: float = 0.0
    heading_rad: float = 0.0
    roll_rad: float = 0.0
    pitch_rad: float = 0.0
    on_ground: bool = False
    terrain_alt_m: float = 0.0


_TRUTH_PROPS = (
    "position/lat-geod-deg",
    "position/long-gc-deg",
    "position/h-sl-ft",
    "velocities/v-north-fps",
    "velocities/v-east-fps",
    "velocities/v-down-fps",
    "attitude/phi-rad",
    "attitude/theta-rad",
    "attitude/psi-rad",
    "velocities/p-rad_sec",
    "velocities/q-rad_sec",
    "velocities/r-rad_sec",
    "velocities/vtrue-fps",
    "velocities/ve-fps",
    "aero/alpha-rad",
    "aero/beta-rad",
)


class JSBSimPlant:
    """A JSBSim model stepped at a fixed ``dt`` [s].

    ``airframe_dir`` is one of this project's airframe folders (``aircraft/<name>/`` holding
    ``<name>.xml`` and its ``engine/`` and ``systems/``); ``None`` loads a model shipped with
    JSBSim (e.g. ``c172p``).
    """

    def __init__(self, model: str, dt: float, origin: GeoPoint, airframe_dir: Path | None = None):
        self.model = model
        self.dt = float(dt)
        self.origin = origin
        self._frame = LocalLevelFrame(origin)
        self._log = _quiet_logger()
        self._log.recent.clear()  # the logger is per thread: warnings count from this plant's load
        self.fdm = jsbsim.FGFDMExec(jsbsim.get_default_root_dir())
        self.fdm.set_debug_level(0)
        self.fdm.set_dt(self.dt)  # before loading: FCS filters and integrators take their dt at load
        if airframe_dir is None:
            ok = self._guard(lambda: self.fdm.load_model(model), f"load shipped model {model!r}")
        else:
            d = Path(airframe_dir)
            ok = self._guard(
                lambda: self.fdm.load_model_with_paths(model, str(d.parent), str(d / "engine"), str(d / "systems")),
                f"load model {model!r} from {d}",
            )
        if not ok:
            raise PlantError(self._with_log(f"JSBSim could not load model {model!r}"))
        self._truth_nodes = self.property_nodes(_TRUTH_PROPS)
        self._truth: VehicleState | None = None  # the last truth read, valid while sim time stands
        self._setters: dict[str, Callable[[float], bool]] = {}  # set_many's property setters by name
        self.after_step: Callable[[], None] | None = None  # called after every integration step

    def property_nodes(self, names: Sequence[str]) -> list[jsbsim.FGPropertyNode]:
        """The model's property nodes of ``names`` (looked up once, read every tick)."""
        pm = self.fdm.get_property_manager()
        nodes = [pm.get_node(name, False) for name in names]
        missing = [name for name, node in zip(names, nodes, strict=True) if node is None]
        if missing:
            raise PlantError(f"JSBSim model has no properties {missing}")
        return [node for node in nodes if node is not None]

    @property
    def warnings(self) -> list[str]:
        """JSBSim's recent warnings and errors since this plant was created (its console is
        silenced; plants of one thread share the logger)."""
        return list(self._log.recent)

    def _with_log(self, msg: str) -> str:
        tail = "; ".join(list(self._log.recent)[-3:])
        return f"{msg}: {tail}" if tail else msg

    def _guard(self, fn, what: str):
        try:
            return fn()
        except (RuntimeError, jsbsim.BaseError) as exc:  # JSBSim raises on XML errors
            raise PlantError(self._with_log(f"JSBSim failed to {what}: {exc}")) from exc

    # -- properties ------------------------------------------------------------------------
    def __getitem__(self, name: str) -> float:
        return self.fdm.get_property_value(name)

    def __setitem__(self, name: str, value: float) -> None:
        self.fdm.set_property_value(name, float(value))

    def set_many(self, values: dict[str, float]) -> None:
        """Set properties by name (created if missing, as ``fdm[name] = value`` does); each
        name's node is looked up once, as controllers write the same commands every tick."""
        setters = self._setters
        for k, v in values.items():
            put = setters.get(k)
            if put is None:
                node = self.fdm.get_property_manager().get_node(k, True)
                if node is None:
                    raise PlantError(f"JSBSim could not create property {k!r}")
                put = setters[k] = node.set_double_value
            put(float(v))

    # -- life cycle ------------------------------------------------------------------------
    def initialise(self, ic: InitialConditions) -> None:
        """Apply initial conditions, start the engines and run the IC."""
        f = self.fdm
        f["ic/lat-geod-deg"] = ic.position.lat_deg
        f["ic/long-gc-deg"] = ic.position.lon_deg
        f["ic/terrain-elevation-ft"] = ic.terrain_alt_m / FT
        if ic.on_ground:
            f["ic/h-agl-ft"] = 0.5  # lower and the gear springs catapult it (jsbsim-notes)
        else:
            f["ic/h-sl-ft"] = ic.position.alt_m / FT
        f["ic/vt-kts"] = ic.tas_mps / KT
        f["ic/psi-true-rad"] = ic.heading_rad
        f["ic/phi-rad"] = ic.roll_rad
        f["ic/theta-rad"] = ic.pitch_rad
        if not self._guard(f.run_ic, "run the initial conditions"):
            raise PlantError(self._with_log(f"{self.model}: run_ic failed"))
        f.get_propulsion().init_running(-1)
        self._truth = None

    def trim(self, mode: int = 1) -> None:
        """JSBSim trim (1 = full longitudinal + lateral); raises PlantError with the reason."""
        self._truth = None
        try:
            self.fdm["simulation/do_simple_trim"] = mode
        except jsbsim.TrimFailureError as exc:
            raise PlantError(self._with_log(f"{self.model}: trim failed ({exc})")) from exc

    def set_wind(self, wind_ned: np.ndarray) -> None:
        """The steady wind (velocity of the air mass, NED [m/s]) from now on; the vehicle keeps
        its ground velocity. JSBSim's IC run and trim reset the wind: set it after them."""
        n, e, d = (float(v) / FT for v in wind_ned)
        f = self.fdm
        f["atmosphere/wind-north-fps"] = n
        f["atmosphere/wind-east-fps"] = e
        f["atmosphere/wind-down-fps"] = d

    def carry_into_wind(self, wind_ned: np.ndarray) -> None:
        """Put the vehicle, as initialised (and trimmed), into a steady wind NED [m/s] with its
        state relative to the air unchanged: attitude, rates and air-relative body velocity stay,
        the ground velocity gains the wind (in uniform wind the trim is Galilean-invariant)."""
        f = self.fdm
        wind = np.asarray(wind_ned, float)
        att = [f[f"attitude/{a}-rad"] for a in ("phi", "theta", "psi")]
        uvw_air = np.array([f["velocities/u-fps"], f["velocities/v-fps"], f["velocities/w-fps"]])
        uvw = uvw_air + euler_to_dcm(*att).T @ (wind / FT)
        values = {
            "ic/lat-geod-deg": f["position/lat-geod-deg"],
            "ic/long-gc-deg": f["position/long-gc-deg"],
            "ic/h-sl-ft": f["position/h-sl-ft"],
            "ic/phi-rad": att[0],
            "ic/theta-rad": att[1],
            "ic/psi-true-rad": att[2],
            "ic/u-fps": uvw[0],
            "ic/v-fps": uvw[1],
            "ic/w-fps": uvw[2],
            "ic/p-rad_sec": f["velocities/p-rad_sec"],
            "ic/q-rad_sec": f["velocities/q-rad_sec"],
            "ic/r-rad_sec": f["velocities/r-rad_sec"],
        }
        self.set_many(values)
        if not self._guard(f.run_ic, "run the initial conditions in the wind"):
            raise PlantError(self._with_log(f"{self.model}: run_ic in the wind failed"))
        self.set_wind(wind)
        f.suspend_integration()  # one pass without time: air data (vt, alpha, beta) in the new wind
        ok = self._guard(f.run, "evaluate the state in the wind")
        f.resume_integration()
        if not ok:
            raise PlantError(self._with_log(f"{self.model}: evaluating the state in the wind failed"))
        self._truth = None

    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps of ``dt``, calling ``after_step`` (if set) after each."""
        run, hook = self.fdm.run, self.after_step
        for _ in range(n):
            if not run():
                raise PlantError(self._with_log(f"{self.model}: JSBSim stopped at t={self.time:.3f} s"))
            if hook is not None:
                hook()

    @property
    def engine_count(self) -> int:
        return self.fdm.get_propulsion().get_num_engines()

    @property
    def time(self) -> float:
        return self.fdm.get_sim_time()

    def kinematics(self) -> tuple[np.ndarray, np.ndarray]:
        """True position and velocity NED now [m, m/s], the values of :meth:`truth`: from
        the truth already read at this sim time, else from its six property reads alone."""
        tr = self._truth
        if tr is not None and tr.t == self.time:
            return tr.pos_ned, tr.vel_ned
        lat, lon, h_ft, vn, ve, vd = (n.get_double_value() for n in self._truth_nodes[:6])
        return np.array(self._frame.ned(lat, lon, h_ft * FT)), np.array([vn * FT, ve * FT, vd * FT])

    def truth(self) -> VehicleState:
        """True state in the scenario frame (SI); read once per sim time (estimator, sensing and
        logging of one tick share it; callers must not modify it)."""
        if self._truth is not None and self._truth.t == self.time:
            return self._truth
        (lat, lon, h_ft, vn, ve, vd, phi, theta, psi, p, q, r, vt, veas, alpha, beta) = (
            n.get_double_value() for n in self._truth_nodes
        )
        alt = h_ft * FT
        self._truth = VehicleState(
            t=self.time,
            pos_ned=np.array(self._frame.ned(lat, lon, alt)),
            vel_ned=np.array([vn * FT, ve * FT, vd * FT]),
            euler=np.array([phi, theta, math.remainder(psi, math.tau)]),  # JSBSim: psi in [0, 2 pi)
            rates_body=np.array([p, q, r]),
            alt_msl_m=alt,
            lat_deg=lat,
            lon_deg=lon,
            tas_mps=vt * FT,
            eas_mps=veas * FT,
            alpha_rad=alpha,
            beta_rad=beta,
        )
        return self._truth
