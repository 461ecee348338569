"""Ctrl-C (and a SIGTERM the CLI turns into one) as a stop request checked once per tick.

Python's Ctrl-C handler raises KeyboardInterrupt at whatever bytecode runs when the signal
arrives; inside a finalizer or a weakref callback that exception is printed and dropped
("Exception ignored in ..."), and the interrupt is lost. While a run flies, :class:`StopRequests`
replaces every handler that is :func:`signal.default_int_handler` (SIGINT's unless the process
was started with it ignored; SIGTERM's under ``cosim``) by one that only sets a flag, which the
run's loop reads after each tick; a second signal before the run stops raises KeyboardInterrupt
as before (the user insists). Handlers can only be set from the main thread: elsewhere (a Dask
worker's task thread) nothing is replaced and the process keeps its own handling.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable
from types import FrameType, TracebackType
from typing import Any

SIGNALS = (signal.SIGINT, signal.SIGTERM)
Handler = Callable[[int, FrameType | None], Any] | int | signal.Handlers | None


class StopRequests:
    """Context manager: ``requested`` turns true at the first interrupting signal; the handlers
    found on entry are restored on exit."""

    def __init__(self) -> None:
        self.requested = False
        self._saved: dict[int, Handler] = {}

    def __enter__(self) -> StopRequests:
        if threading.current_thread() is threading.main_thread():
            for sig in SIGNALS:
                if signal.getsignal(sig) is signal.default_int_handler:
                    self._saved[sig] = signal.signal(sig, self._request)
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        for sig, handler in self._saved.items():
            signal.signal(sig, handler)
        self._saved.clear()

    def _request(self, signum: int, frame: FrameType | None) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True
