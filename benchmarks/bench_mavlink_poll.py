"""Cost of hostile MAVLink traffic to the simulation thread: one ``VehicleLink.poll()`` while a
flood of datagrams waits, against the unbounded baseline measured in the same run (decoding
every waiting datagram in full, as the link did before its receive bounds).

Traffic kinds: random bytes (``random``), datagrams starting with the MAVLink 2 frame marker then
random bytes (``crafted``: what defeats the frame-start pre-filter) and 64 KiB datagrams
(``huge``). For each: 40 datagrams are queued, one ``poll()`` is timed, the queue is drained;
20 repetitions, median and maximum [ms]. Baseline: parsing the same 40 datagrams at their full
size (64 KiB ones at 64 KiB) with a robust pymavlink parser, no pre-filter. Wall-clock numbers:
take them on an idle machine.

    python benchmarks/bench_mavlink_poll.py
"""

from __future__ import annotations

import os
import random
import socket
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("MAVLINK20", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pymavlink.dialects.v20 import common as mav

from sim.mavlink import LinkConfig, VehicleLink

N_DATAGRAMS, REPEATS = 40, 20


def _traffic(kind: str, rng: random.Random) -> list[bytes]:
    if kind == "random":
        return [rng.randbytes(1024) for _ in range(N_DATAGRAMS)]
    if kind == "crafted":
        return [b"\xfd" + rng.randbytes(1023) for _ in range(N_DATAGRAMS)]
    return [b"\xfd" + rng.randbytes(65000) for _ in range(N_DATAGRAMS)]


def main() -> None:
    rng = random.Random(1)
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sender.bind(("127.0.0.1", 0))
    sender.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 1 << 22)
    link = VehicleLink(LinkConfig(system_id=1, gcs_port=sender.getsockname()[1]))
    link._sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 23)  # hold the whole flood
    print(f"{'traffic':8} {'poll median':>12} {'poll max':>9} {'baseline median':>16} {'ratio':>6}")
    for kind in ("random", "crafted", "huge"):
        polls, base = [], []
        for _ in range(REPEATS):
            data = _traffic(kind, rng)
            for d in data:
                sender.sendto(d, link.local_address)
            time.sleep(0.02)
            t0 = time.perf_counter()
            link.poll()
            polls.append(time.perf_counter() - t0)
            while _drain(link):
                pass
            t0 = time.perf_counter()
            for d in data:
                _parse_in_full(d)
            base.append(time.perf_counter() - t0)
        pm, bm = statistics.median(polls), statistics.median(base)
        print(f"{kind:8} {pm * 1e3:10.2f} ms {max(polls) * 1e3:6.2f} ms {bm * 1e3:13.2f} ms {bm / pm:6.0f}x")
    link.close()


def _parse_in_full(data: bytes) -> None:
    """The unbounded baseline: a robust pymavlink parse of the whole datagram."""
    parser = mav.MAVLink(None)
    parser.robust_parsing = True
    parser.parse_buffer(data)


def _drain(link: VehicleLink) -> bool:
    """Read one waiting datagram without parsing it; False when none is left."""
    try:
        link._sock.recv(70000)
    except BlockingIOError:
        return False
    return True


if __name__ == "__main__":
    main()
