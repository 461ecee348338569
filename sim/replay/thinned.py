"""Time series kept for plots in bounded memory: every ``stride``-th sample, the stride doubling
whenever more than ``limit`` samples are kept (the first sample always stays)."""

from __future__ import annotations

import numpy as np


class Thinned:
    """Named columns of equal length, appended chunk by chunk and thinned to at most ``limit``
    rows: row i of the whole series is kept when i is a multiple of the current stride."""

    def __init__(self, limit: int = 8192):
        if limit < 2:
            raise ValueError(f"limit must be at least 2, got {limit}")
        self.limit = limit
        self.stride = 1
        self.seen = 0  # rows appended so far
        self.columns: dict[str, np.ndarray] = {}

    def add(self, **columns: np.ndarray) -> None:
        """Rows that follow the previous ones (every column the same length)."""
        n = len(next(iter(columns.values()))) if columns else 0
        if not n:
            return
        first = (-self.seen) % self.stride  # index in this chunk of the next multiple of the stride
        self.seen += n
        for name, values in columns.items():
            kept = np.asarray(values)[first :: self.stride]
            old = self.columns.get(name)
            self.columns[name] = kept if old is None else np.concatenate([old, kept])
        while len(self) > self.limit:
            self.stride *= 2
            self.columns = {k: v[::2] for k, v in self.columns.items()}

    def __len__(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]
