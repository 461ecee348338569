"""Per-tick topics written as rows (sim.log_rows): a compact log reads back, message for message,
what the JSON log of the same flight holds (the sensors' measured values rounded to float32, as
cosim.Sensors stores them)."""

from __future__ import annotations

import numpy as np
import pytest

from sim.log_rows import COMMANDS, ENERGY, SIGMA_INPUTS, flatten, row_dict
from sim.mcap_log import ROWS
from sim.mcap_read import read_info
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
