"""Per-tick topics written as rows (sim.log_rows): a compact log reads back, message for message,
what the JSON log of the same flight holds (the sensors' measured values rounded to float32, as
cosim.Sensors stores them)."""

from __future__ import annotations

from array import array

import numpy as np
import pytest

from sim import log_schemas as S
from sim.core.state import VehicleState
from sim.energy.power_system import EnergyRecord
from sim.log_rows import COMMANDS, ENERGY, SIGMA_INPUTS, flatten, row_dict
from sim.mcap_log import ROWS, LogWriteError, McapLog
from sim.mcap_read import iter_messages, read_info
from sim.vehicle_log import VehicleLogWriter
from tests.test_log_proto import _float32

ROW_TOPICS = (
    "truth/state",
    "truth/location",
    "truth/tracking",
    "est/state",
    "sensors",
    "est/sigma3",
    "ctrl/setpoint",
    "ctrl/commands",
)


def _plain(msg):
    """A cosim message's dict, a Foxglove message's bytes (classes differ between two files)."""
    return msg if isinstance(msg, dict) else msg.SerializeToString(deterministic=True)


def _both(fly, scenario_data, name: str, seconds: float, rate_hz: float | None):
    logs = {}
    for enc in ("protobuf", "json"):
        data = scenario_data(name)
        data.setdefault("logging", {})["encoding"] = enc
        if rate_hz:
            data["logging"]["rate_hz"] = rate_hz
        logs[enc] = fly(data, name=enc, duration=seconds)
    return logs["protobuf"], logs["json"]


@pytest.mark.parametrize(
    ("scenario", "rate_hz", "extra"),
    [("mixed_haps_quad", None, ()), ("haps_station_june_47n", 10.0, ("energy",))],
)
def test_row_topics_read_back_what_the_json_log_holds(fly, scenario_data, scenario, rate_hz, extra):
    """Several blocks of rows per topic, sensors with varying records per tick, two vehicles on
    ``/tf``, the energy bus."""
    compact, js = _both(fly, scenario_data, scenario, 4.0, rate_hz)
    topics = [f"/{v}/{k}" for v in compact.log.vehicles for k in (*ROW_TOPICS, *extra)] + ["/tf"]
    encodings = {t.topic: t.encoding for t in read_info(compact.path).topics}
    assert len(compact.log.topic("/haps/truth/state")) > ROWS
    for topic in topics:
        assert encodings[topic] == "protobuf", topic
        a, b = compact.log.topic(topic), js.log.topic(topic)
        assert np.array_equal(a.t, b.t), topic
        want = [_float32(m) for m in b.messages] if topic.endswith("/sensors") else b.messages
        assert [_plain(m) for m in a.messages] == [_plain(m) for m in want], topic


def test_flatten_and_row_dict_invert_each_other():
    sigma = {
        "t": 1.5,
        "var": [0.5 * k for k in range(16)],
        "q": [0.5, 0.5, -0.5, 0.5],
        "p_att": [1e-4 * k for k in range(9)],
        "bias": {"accel": [0.0, 0.1, 0.2], "gyro": [1e-5, 0.0, -1e-5], "baro": [-3.0], "gnss_gm": [0.3, -0.2, 1.1]},
    }
    cmd = {"t": 2.0, "properties": {"fcs/throttle-cmd-norm": 0.7, "fcs/aileron-cmd-norm": -0.1}, "debug": {"x": 1.0}}
    for columns, d in ((SIGMA_INPUTS, sigma), (COMMANDS, cmd)):
        row, static = flatten(columns, d)
        assert row_dict(columns, row, static, {}) == d
    energy = {k: float(i) for i, (k, w) in enumerate(ENERGY) if w == 0}
    energy |= {"depleted": True, "cumulative_wh": {"solar": 3.0, "loads": 1.0}}
    row, static = flatten(ENERGY, energy)
    assert row_dict(ENERGY, row, static, {"depleted": bool}) == energy


def _tick(w, t: float, energy) -> None:
    """One tick of a fixed-wing vehicle without a sensor estimator."""
    s = VehicleState(t, np.array([1.0, 2.0, -3.0]), np.zeros(3), np.array([0.1, 0.2, 0.3]), np.zeros(3), 3.0, 47.0, 8.0)
    sp = {"roll_rad": 0.1, "altitude_m": 3.0, "tas_mps": 9.0, "leg": 1, "cross_track_m": 0.5, "turning": False}
    w.tick(t, s, (0.5, 1), s, None, (sp, S.FIXED_WING_SETPOINT, {"fcs/throttle-cmd-norm": 0.4}, {}), energy)


def test_a_tick_logs_what_its_inputs_held_at_the_tick(tmp_path):
    """The bus record changes in place every control step: a compact log's row holds its values
    at the tick, not at the hand-over to the writer (the states and control dicts are new each
    step, a quadrotor's debug dict is copied by the vehicle: the JSON comparison above covers
    those)."""
    log = McapLog(tmp_path / "a.mcap", 0, background=False)
    w = VehicleLogWriter(log, "v")
    record = EnergyRecord(solar_w=10.0)
    _tick(w, 0.1, record)
    record.solar_w, record.cumulative_wh["solar"] = 20.0, 5.0  # the next control step
    _tick(w, 0.2, record)
    log.close()
    got = {(topic, t): msg for topic, t, msg in iter_messages(log.path)}
    assert [got["/v/energy", t]["solar_w"] for t in (0.1, 0.2)] == [10.0, 20.0]
    assert [got["/v/energy", t]["cumulative_wh"]["solar"] for t in (0.1, 0.2)] == [0.0, 5.0]


def test_a_block_whose_values_do_not_fit_its_specs_is_an_error(tmp_path):
    """The writer checks a block's values against its rows' widths (a row of the wrong width
    would shift every later row's columns)."""
    log = McapLog(tmp_path / "a.mcap", 0, background=False)
    spec = log.row_spec((("tracking", ("/v/truth/tracking",), (), ({},)),))
    rows = ("rows", 0, [spec, spec], array("d", [0.1, 0.5, 1.0, 0.2, 0.5]).tobytes())
    log._record(rows)
    with pytest.raises(LogWriteError, match="5 values, its specs take 6"):
        log.close()
