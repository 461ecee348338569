"""Batch resume and worker lifetime: an interrupted run is flown again on resume, an edited
batch re-flies exactly the runs whose resolved scenario changed, and pool workers die with the
batch process (SIGKILL or SIGTERM of the parent alone)."""

import os
import signal
import subprocess
import sys
import threading
import time
import tomllib
from concurrent.futures import Executor, Future
from pathlib import Path

import pytest
import tomli_w

from sim.batch import load_batch, run_batch, scenario_hash
from sim.replay.runlog import RunLog

ROOT = Path(__file__).resolve().parents[1]
QUAD = ROOT / "scenarios" / "quad_square_mission.toml"
pytestmark = pytest.mark.closed_loop


class InlineExecutor(Executor):
    """Runs each submitted call at once in the calling (main) thread, so that a SIGINT reaches
    the run itself."""

    def submit(self, fn, /, *args, **kwargs):
        f = Future()
        f.set_result(fn(*args, **kwargs))
        return f


def _batch(tmp_path: Path, speeds: str, duration: str = "30 s", hover: bool = False) -> Path:
    """A sweep over the quadrotor's cruise speed; ``hover``: over a quadrotor hovering for the
    whole ``duration`` instead of its short square mission (runs that last)."""
    base = QUAD
    if hover:
        data = tomllib.loads(QUAD.read_text())
        data["vehicle"][0]["mission"].update(
            land=False, waypoints=[{"north": 0, "east": 0, "altitude": 415, "hold": "1 h"}]
        )
        base = tmp_path / "hover.toml"
        base.write_text(tomli_w.dumps(data))
    f = tmp_path / "b.toml"
    f.write_text(
        f'base = "{base}"\nname = "resume"\nduration = "{duration}"\n'
        f'[sweep]\n"vehicle.0.mission.cruise_speed" = [{speeds}]\n'
    )
    return f


def _flown(runs, out) -> list[str]:
    calls: list[str] = []
    run_batch(runs, out, executor=InlineExecutor(), progress=lambda k, n, row: calls.append(row["run_id"]))
    return sorted(calls)


@pytest.mark.usefixtures("ctrl_c_raises")
def test_interrupted_run_is_flown_again_on_resume(tmp_path):
    out = tmp_path / "out"
    _, runs = load_batch(_batch(tmp_path, "3, 4", duration="120 s", hover=True), out)
    first_log = Path(runs[0].log_path)

    def interrupt_the_first_run():
        while not first_log.exists():
            time.sleep(0.01)
        time.sleep(1.0)  # flying
        os.kill(os.getpid(), signal.SIGINT)

    threading.Thread(target=interrupt_the_first_run, daemon=True).start()
    rows = run_batch(runs, out, executor=InlineExecutor())
    assert [r["status"] for r in rows] == ["interrupted", "duration_elapsed"]
    assert not Path(runs[0].result_path).exists() and Path(runs[1].result_path).exists()
    assert _flown(runs, out) == ["resume_0000"]  # only the interrupted one
    assert _flown(runs, out) == []


def test_edited_batch_re_flies_what_changed(tmp_path):
    out = tmp_path / "out"
    _, runs = load_batch(_batch(tmp_path, "3, 4"), out)
    assert _flown(runs, out) == ["resume_0000", "resume_0001"]
    _, edited = load_batch(_batch(tmp_path, "3, 5"), out)
    assert scenario_hash(edited[0]) == scenario_hash(runs[0]) != scenario_hash(edited[1])
    assert _flown(edited, out) == ["resume_0001"]
    _, longer = load_batch(_batch(tmp_path, "3, 5", duration="31 s"), out)
    assert _flown(longer, out) == ["resume_0000", "resume_0001"]


def _alive(pid: int) -> bool:
    """Running (not gone, not a zombie waiting for a reaper)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _children(pid: int) -> list[int]:
    return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_pool_workers_die_with_the_batch_process(tmp_path, sig):
    batch = _batch(tmp_path, "3, 4, 5, 6", duration="600 s", hover=True)
    proc = subprocess.Popen(
        [sys.executable, "-m", "sim.cli", "batch", str(batch), "-o", str(tmp_path / "out"), "--workers", "2", "-q"],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        end = time.monotonic() + 60
        while time.monotonic() < end and len(workers := _children(proc.pid)) < 2:
            time.sleep(0.1)
        time.sleep(2.0)  # flying
        workers = [w for w in _children(proc.pid) if _alive(w)]
        assert len(workers) >= 2
        os.kill(proc.pid, sig)  # the parent alone, not its group
        proc.wait(timeout=30)
        end = time.monotonic() + 20
        while time.monotonic() < end and any(_alive(w) for w in workers):
            time.sleep(0.1)
        assert not any(_alive(w) for w in workers)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)


def test_batch_started_with_sigint_ignored_keeps_ignoring_it_and_stops_on_sigterm(tmp_path):
    """A background job of a script is started with SIGINT ignored, as its shell asks: Ctrl-C
    leaves it flying; SIGTERM (``kill PID``) interrupts it like Ctrl-C (exit 130, the run
    interrupted, flown again on resume)."""
    batch = _batch(tmp_path, "3", duration="36000 s", hover=True)  # never done by itself: the signals stop it
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "sim.cli", "batch", str(batch), "-o", str(out), "--workers", "1", "-q"]
    proc = subprocess.Popen(
        ["sh", "-c", 'trap "" INT; exec "$@"', "sh", *cmd],  # SIGINT ignored across the exec
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        log = out / "runs" / "resume_0000.mcap"
        end = time.monotonic() + 120
        while time.monotonic() < end and not log.exists():
            time.sleep(0.1)
        assert log.exists()
        time.sleep(1.0)  # flying
        os.kill(proc.pid, signal.SIGINT)
        time.sleep(2.0)
        assert proc.poll() is None, "a batch that ignores SIGINT stopped on one"
        os.kill(proc.pid, signal.SIGTERM)
        _, stderr = proc.communicate(timeout=60)
        assert proc.returncode == 130, stderr
        assert stderr.strip().endswith("interrupted")
        assert not (out / "runs" / "resume_0000.json").exists()
        # the worker got the SIGTERM too: its run stopped and closed its log, not killed
        assert RunLog(log).metadata["result"]["status"] == "interrupted"
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
