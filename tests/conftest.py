"""Shared test configuration and the scenario / run / log plumbing the test files share.

Hypothesis runs derandomised by default (profile ``ci``: the same examples on every run, so CI is
never red by chance); ``--hypothesis-profile=random`` searches new examples (``max_examples`` x 5).

Fixtures:
- ``scenario_data(name)``: a shipped scenario (``scenarios/<name>.toml``) as a fresh TOML mapping,
  to edit before flying it;
- ``fly(scenario, name=None, **run_options)``: fly a shipped scenario (by name) or an edited
  mapping, logging to ``tmp_path/<name>.mcap``; returns a :class:`Flight` (result, log path, log);
- ``fly_in``: the same with the output folder first (for module-scoped runs);
- ``cosim(*args, timeout=SUBPROCESS_TIMEOUT_S)``: the ``cosim`` command line in a subprocess from
  the repository root (its exit code is for the test to check).
"""

from __future__ import annotations

import signal
import subprocess
import sys
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property, partial
from pathlib import Path
from typing import Any

import pytest
import tomli_w
from hypothesis import settings

from sim.replay.runlog import RunLog
from sim.runner import RunResult, run_scenario
from sim.scenario import Scenario, load_scenario, parse_scenario

settings.register_profile("ci", derandomize=True, print_blob=True)
settings.register_profile("random", derandomize=False, max_examples=500, print_blob=True)
settings.load_profile("ci")

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"
# A subprocess's upper bound [s], against a hang only: on a loaded 2-core machine the CLI's imports
# alone have taken 25 s of wall time for 2.4 s of CPU.
SUBPROCESS_TIMEOUT_S = 600.0


@dataclass(frozen=True)
class Flight:
    """One logged run: the scenario flown, the runner's result, the log file and (read on first
    use) the whole log."""

    scenario: Scenario
    result: RunResult
    path: Path

    @cached_property
    def log(self) -> RunLog:
        return RunLog(self.path)


def _shipped(name: str) -> Path:
    return SCENARIOS / f"{name}.toml"


def _fly_in(out_dir: Path, scenario: str | dict[str, Any], name: str | None = None, **run_options: Any) -> Flight:
    """Fly ``scenario`` (a shipped scenario's name, e.g. ``"geometric/head_on"``, or a scenario
    mapping) with ``run_options`` of :func:`sim.runner.run_scenario`; the log is
    ``out_dir/<name>.mcap`` (default name: the scenario's last path part, or ``run``) and keeps
    the scenario's TOML text."""
    if isinstance(scenario, str):
        sc, text = load_scenario(_shipped(scenario))
        name = name or Path(scenario).name
    else:
        text = tomli_w.dumps(scenario)
        sc = parse_scenario(scenario, name or "<scenario>")
        name = name or "run"
    path = out_dir / f"{name}.mcap"
    return Flight(sc, run_scenario(sc, path, scenario_text=text, **run_options), path)


@pytest.fixture(scope="session")
def scenario_data() -> Callable[[str], dict[str, Any]]:
    def load(name: str) -> dict[str, Any]:
        return tomllib.loads(_shipped(name).read_text())

    return load


@pytest.fixture(scope="session")
def fly_in() -> Callable[..., Flight]:
    return _fly_in


@pytest.fixture
def fly(tmp_path: Path) -> Callable[..., Flight]:
    return partial(_fly_in, tmp_path)


@pytest.fixture(scope="session")
def cosim() -> Callable[..., subprocess.CompletedProcess[str]]:
    def run(*args: str, timeout: float = SUBPROCESS_TIMEOUT_S) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "sim.cli", *map(str, args)],
            capture_output=True,
            text=True,
            cwd=ROOT,
            timeout=timeout,
            check=False,
        )

    return run


@pytest.fixture
def ctrl_c_raises():
    """Python's Ctrl-C handler (KeyboardInterrupt) for the test, the previous one back after it.
    A process started with SIGINT ignored keeps it ignored (POSIX; Python installs its handler
    only over the default): a test suite started as a background job of a non-interactive shell
    (``pytest ... &`` in a script), and every xdist worker it starts, would not see the SIGINT
    this test sends."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)
