"""MCAP writer/reader round trip, crash safety and clear errors on bad files."""

import contextlib
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from foxglove_schemas_protobuf.LocationFix_pb2 import LocationFix

from sim.log_schemas import MISSION_STATUS
from sim.mcap_log import LogWriteError, McapLog
from sim.mcap_read import LogReadError, iter_messages, read_info, read_topic

EPOCH = 1_782_021_600_000_000_000


def _write(path, n=50, fail_at=None):
    with McapLog(path, EPOCH) as log:
        log.metadata("run", {"epoch_ns": EPOCH, "scenario": "unit"})
        log.attach("scenario.toml", b"name='unit'", "application/toml")
        for k in range(n):
            t = k * 0.1
            if fail_at is not None and k == fail_at:
                raise RuntimeError("injected")
            log.write_json(
                "/v/mission/status", t, {"t": t, "next_waypoint": k, "waypoints": n, "complete": False}, MISSION_STATUS
            )
            fix = LocationFix(latitude=47.0 + k * 1e-5, longitude=8.0, altitude=18000.0)
            log.write_proto("/v/truth/location", t, fix)
        log.event(n * 0.1, "done")


def test_round_trip_json_proto_events_metadata(tmp_path):
    p = tmp_path / "a.mcap"
    _write(p)
    info = read_info(p)
    assert info.metadata["run"]["scenario"] == "unit"
    assert info.attachments == ["scenario.toml"]
    counts = {t.topic: t.count for t in info.topics}
    assert counts == {"/v/mission/status": 50, "/v/truth/location": 50, "/log": 1}
    assert info.start_s == 0.0 and info.end_s == pytest.approx(5.0)
    status = read_topic(p, "/v/mission/status")
    assert [m["next_waypoint"] for _, m in status] == list(range(50))
    assert status[7][0] == pytest.approx(0.7)
    fixes = read_topic(p, "/v/truth/location")
    assert fixes[3][1].latitude == pytest.approx(47.00003)
    ((_, t, log),) = list(iter_messages(p, ["/log"]))
    assert log.message == "done" and t == pytest.approx(5.0)


def test_exception_mid_write_leaves_readable_file(tmp_path):
    p = tmp_path / "crash.mcap"
    with pytest.raises(RuntimeError, match="injected"):
        _write(p, fail_at=30)
    status = read_topic(p, "/v/mission/status")
    assert len(status) == 30 and status[-1][1]["next_waypoint"] == 29


def test_same_content_same_bytes(tmp_path):
    _write(tmp_path / "1.mcap")
    _write(tmp_path / "2.mcap")
    assert (tmp_path / "1.mcap").read_bytes() == (tmp_path / "2.mcap").read_bytes()


def test_not_an_mcap_is_a_clear_error(tmp_path):
    p = tmp_path / "junk.mcap"
    p.write_bytes(b"this is not an mcap file at all" * 10)
    with pytest.raises(LogReadError, match="not a readable MCAP"):
        read_info(p)
    with pytest.raises(LogReadError, match="no such file"):
        read_info(tmp_path / "missing.mcap")


@pytest.mark.parametrize("keep", [0.3, 0.5, 0.999])
def test_unfinished_file_is_read_up_to_its_last_complete_chunk(tmp_path, keep):
    """A log cut anywhere (its writer killed, a full disk) reads as the messages of its complete
    chunks: a prefix of the full log, flagged unfinished."""
    p = tmp_path / "full.mcap"
    with McapLog(p, EPOCH, chunk_size=4096) as log:
        log.metadata("run", {"epoch_ns": EPOCH})
        for k in range(3000):
            log.write_json("/v/mission/status", k * 0.1, {"t": k * 0.1, "next_waypoint": k}, MISSION_STATUS)
    data = p.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * keep)])
    info = read_info(cut)
    assert not info.finished and read_info(p).finished
    status = read_topic(cut, "/v/mission/status")
    assert 0 < len(status) == info.messages <= 3000  # 0.999: only the summary is lost
    assert len(status) > 3000 * keep - 400  # at most about one chunk lost
    assert [m["next_waypoint"] for _, m in status] == list(range(len(status)))
    assert info.end_s == pytest.approx(status[-1][0])


@pytest.mark.parametrize("keep", [0, 5, 20])
def test_file_cut_inside_its_header_is_a_clear_error(tmp_path, keep):
    p = tmp_path / "full.mcap"
    _write(p, n=30)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(p.read_bytes()[:keep])
    with pytest.raises(LogReadError, match="not a readable MCAP file"):
        read_info(cut)


def test_inline_and_background_writers_write_the_same_bytes(tmp_path):
    for background in (True, False):
        with McapLog(tmp_path / f"{background}.mcap", EPOCH, background=background) as log:
            for k in range(300):  # several hand-overs to the writer process
                log.write_json(
                    "/v/mission/status",
                    k * 0.1,
                    {"t": k * 0.1, "next_waypoint": k, "waypoints": 300, "complete": False},
                    MISSION_STATUS,
                )
    assert (tmp_path / "True.mcap").read_bytes() == (tmp_path / "False.mcap").read_bytes()


def test_unwritable_path_is_a_clear_error_at_once(tmp_path):
    with pytest.raises(LogWriteError, match="cannot write the log"):
        McapLog(tmp_path, EPOCH)  # a directory


_KILLED_WRITER = """
import os, signal, sys
from sim.log_schemas import MISSION_STATUS
from sim.mcap_log import LogWriteError, McapLog
log = McapLog(sys.argv[1], {epoch})
for k in range(1000):
    log.write_json("/v/mission/status", k * 0.1, {{"t": k * 0.1, "next_waypoint": k, "waypoints": 1000,
                                                 "complete": False}}, MISSION_STATUS)
os.kill(os.getpid(), signal.SIGKILL)  # no close(), no finally: as if the flight model crashed
"""


def test_killed_simulation_process_still_leaves_a_finished_log(tmp_path):
    """The writer process finishes the file when the simulation process dies without closing it:
    every handed-over message is readable, and the summary is there."""
    p = tmp_path / "killed.mcap"
    run = subprocess.run(
        [sys.executable, "-c", _KILLED_WRITER.format(epoch=EPOCH), str(p)],
        cwd=Path(__file__).resolve().parents[1],
        timeout=60,
        check=False,
    )
    assert run.returncode == -signal.SIGKILL
    for _ in range(100):  # the orphaned writer finishes on its own, shortly after
        with contextlib.suppress(LogReadError):
            if read_info(p).finished:
                break
        time.sleep(0.1)
    assert read_info(p).finished
    counts = {t.topic: t.count for t in read_info(p).topics}
    assert counts["/v/mission/status"] >= 1000 - 128  # all but the last unsent batch
    status = read_topic(p, "/v/mission/status")
    assert [m["next_waypoint"] for _, m in status] == list(range(len(status)))


def test_a_script_without_main_guard_runs_once(tmp_path):
    """The writer process must not re-run the caller's script (a multiprocessing child would)."""
    script = tmp_path / "user_script.py"
    marker = tmp_path / "runs.txt"
    script.write_text(
        "from sim.mcap_log import McapLog\n"
        f"open({str(marker)!r}, 'a').write('x')\n"
        f"with McapLog({str(tmp_path / 'u.mcap')!r}, {EPOCH}) as log:\n"
        "    log.event(0.0, 'hello')\n"
    )
    subprocess.run([sys.executable, str(script)], cwd=Path(__file__).resolve().parents[1], timeout=60, check=True)
    assert marker.read_text() == "x"
    assert next(m for _, m in read_topic(tmp_path / "u.mcap", "/log")).message == "hello"
