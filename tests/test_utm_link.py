"""The modelled C2/UTM link (sim/utm_link.py): latency, loss, outages, delivery order."""

import numpy as np

from sim.utm_link import Link, Queue


def test_latency_and_outage_windows():
    link = Link(0.5, 0.0, ((10.0, 20.0),), np.random.default_rng(0))
    assert link.arrival(1.0) == 1.5
    assert link.arrival(9.6) is None  # due inside the outage
    assert link.arrival(15.0) is None and not link.up(15.0)
    assert link.arrival(20.0) == 20.5 and link.up(20.0)


def test_loss_rate_matches_the_probability():
    link = Link(0.0, 0.2, (), np.random.default_rng(1))
    lost = sum(link.arrival(float(k)) is None for k in range(5000))
    assert abs(lost / 5000 - 0.2) < 0.02


def test_queue_delivers_what_arrived_in_arrival_then_sending_order():
    q = Queue()
    q.put(2.0, "b")
    q.put(1.0, "a")
    q.put(2.0, "c")
    assert q.due(0.5) == []
    assert q.due(2.0) == ["a", "b", "c"]
    assert q.due(10.0) == []
