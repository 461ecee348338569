"""Logs survive: a signal to the whole process group of ``cosim run`` (terminal hang-up, kill of
the group, SIGKILL included) leaves a finished log; a log whose writer died too is read up to
its last complete chunk by ``cosim info`` and ``cosim replay``; a full disk (a file size limit
here) is a one-line error and leaves the log readable up to its last complete chunk."""

import os
import resource
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import pytest
import tomli_w

from sim.mcap_read import LogReadError, read_info
from sim.replay.runlog import RunLog

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.closed_loop


def _hover(folder: Path) -> Path:
    """The quadrotor hovering for 10 min of sim time (many seconds of wall time)."""
    data = tomllib.loads((ROOT / "scenarios" / "quad_square_mission.toml").read_text())
    data["duration"] = 600.0
    v = data["vehicle"][0]
    v["mission"]["land"] = False
    v["mission"]["waypoints"] = [{"north": 0, "east": 0, "altitude": 415, "hold": "600 s"}]
    path = folder / "hover.toml"
    path.write_text(tomli_w.dumps(data))
    return path


def _start(log: Path, fsize_limit: int | None = None) -> subprocess.Popen:
    """``cosim run`` of the hover as the leader of its own process group (so that the test can
    signal the whole group without signalling itself), with SIGHUP at its default action (a test
    run under ``nohup``, signal ignored and inherited through exec, must still see what a hang-up
    does) and, when given, a file size limit [bytes]."""

    def child_setup() -> None:
        signal.signal(signal.SIGHUP, signal.SIG_DFL)
        if fsize_limit is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize_limit, fsize_limit))

    return subprocess.Popen(
        [sys.executable, "-m", "sim.cli", "run", str(_hover(log.parent)), "-o", str(log), "-q"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=child_setup,  # noqa: PLW1509 - only signal and rlimit calls between fork and exec
    )


def _children(pid: int) -> list[int]:
    return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]


def _wait_until_running(proc: subprocess.Popen, log: Path, sim_s: float = 6.0) -> None:
    """Until the simulation flies: its writer started and the log's complete chunks reach
    ``sim_s`` [s] of sim time (on a loaded machine that takes many seconds of wall time)."""
    end = time.monotonic() + 120
    while time.monotonic() < end and proc.poll() is None:
        if _children(proc.pid) and log.exists():
            try:
                if read_info(log).end_s > sim_s:
                    return
            except LogReadError:
                pass
        time.sleep(0.2)
    assert proc.poll() is None, "the run ended before the signal"
    raise AssertionError(f"the log did not reach {sim_s} s of sim time in 120 s")


def _finished_info(log: Path, timeout: float = 20.0):
    end = time.monotonic() + timeout
    while True:
        try:
            info = read_info(log)
            if info.finished or time.monotonic() > end:
                return info
        except LogReadError:
            if time.monotonic() > end:
                raise
        time.sleep(0.1)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGKILL])
def test_group_signal_leaves_a_finished_log(tmp_path, sig):
    log = tmp_path / "run.mcap"
    proc = _start(log)
    _wait_until_running(proc, log)
    os.killpg(proc.pid, sig)
    proc.wait(timeout=30)
    info = _finished_info(log)
    assert info.finished
    assert info.end_s > 5.0 and info.messages > 500
    truth = RunLog(log).topic("/quad/truth/state")
    assert len(truth) > 50


def test_log_of_a_killed_writer_is_recovered_by_info_and_replay(tmp_path):
    log = tmp_path / "run.mcap"
    proc = _start(log)
    _wait_until_running(proc, log)
    children = _children(proc.pid)
    assert len(children) == 1, (children, proc.poll(), proc.stderr.read() if proc.poll() is not None else "")
    (writer,) = children
    os.kill(writer, signal.SIGKILL)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    info = read_info(log)
    assert not info.finished and info.messages > 0
    out = subprocess.run(
        [sys.executable, "-m", "sim.cli", "info", str(log)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert out.returncode == 0, out.stderr
    assert "unfinished" in out.stdout
    rep = subprocess.run(
        [sys.executable, "-m", "sim.cli", "replay", str(log), "-o", str(tmp_path / "rep")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert rep.returncode == 0, rep.stderr
    assert "unfinished log" in rep.stderr
    assert "unfinished log" in (tmp_path / "rep" / "report.md").read_text()
    assert len(RunLog(log).topic("/quad/truth/state")) > 10


def test_full_disk_is_a_one_line_error_and_the_log_stays_readable(tmp_path):
    log = tmp_path / "run.mcap"
    limit = 400_000  # bytes: a few chunks of the run's log
    proc = _start(log, fsize_limit=limit)
    _out, err = proc.communicate(timeout=300)
    assert proc.returncode == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert str(log) in lines[0] and "File too large" in lines[0] and "last complete chunk" in lines[0]
    assert log.stat().st_size <= limit
    info = read_info(log)
    assert not info.finished and info.messages > 100
    assert len(RunLog(log).topic("/quad/truth/state")) > 10
