"""Ctrl-C during a run: a stop request read once per tick, never an exception that a finalizer
can swallow (sim/stop_requests.py)."""

from __future__ import annotations

import gc
import signal
from pathlib import Path

import pytest

from sim.replay.runlog import RunLog
from sim.runner import run_scenario
from sim.scenario import load_scenario
from sim.stop_requests import StopRequests

ROOT = Path(__file__).resolve().parents[1]


class _InterruptedFinalizer:
    """Sends Ctrl-C to its own process from ``__del__``: Python runs the handler there, where a
    KeyboardInterrupt is printed as "Exception ignored in ..." and dropped."""

    def __del__(self):
        signal.raise_signal(signal.SIGINT)
        self.after = True  # bytecode after the signal: the handler runs inside the finalizer


@pytest.mark.usefixtures("ctrl_c_raises")
def test_a_ctrl_c_delivered_inside_a_finalizer_still_stops_the_run(tmp_path):
    scenario, text = load_scenario(ROOT / "scenarios" / "quad_hover_offset.toml")
    seen: list[float] = []

    def hook(t: float) -> None:
        seen.append(t)
        if len(seen) == 20:
            _InterruptedFinalizer()  # dropped at once: its __del__ runs here
            gc.collect()

    result = run_scenario(scenario, tmp_path / "run.mcap", scenario_text=text, duration=600.0, tick_hook=hook)
    assert result.status == "interrupted"
    assert result.sim_time_s < 0.5 * 600.0  # stopped where it was asked, not at the end
    assert RunLog(tmp_path / "run.mcap").metadata["result"]["status"] == "interrupted"
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the handler is back


@pytest.mark.usefixtures("ctrl_c_raises")
def test_a_second_ctrl_c_raises_and_an_ignored_one_stays_ignored():
    with StopRequests() as stop:
        assert not stop.requested
        signal.raise_signal(signal.SIGINT)
        assert stop.requested  # the first one only asks
        with pytest.raises(KeyboardInterrupt):
            signal.raise_signal(signal.SIGINT)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    with StopRequests() as stop:
        signal.raise_signal(signal.SIGINT)
        assert not stop.requested
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
