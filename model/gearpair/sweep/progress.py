"""The progress bar of a sweep on a stream."""

from __future__ import annotations

import math
import sys
import time


class Progress:
    """A progress bar on a stream: redrawn in place on a terminal, else a line every 5 %."""

    def __init__(self, total: int, label: str, stream=None, enabled: bool = True) -> None:
        self.total, self.label, self.done, self.failed = total, label, 0, 0
        self.stream = sys.stderr if stream is None else stream
        self.enabled = enabled
        self.t0 = time.perf_counter()
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._next = 0

    def start(self) -> None:
        """Start the clock (after the cluster is up, so the rate is the computation's)."""
        self.t0 = time.perf_counter()

    def update(self, ok: bool, retrying: bool = False) -> None:
        if not retrying:
            self.done += 1
            self.failed += 0 if ok else 1
        if not self.enabled:
            return
        if not self.tty and self.done < self._next and self.done < self.total:
            return
        self._next = self.done + max(1, self.total // 20)
        dt = time.perf_counter() - self.t0
        rate = self.done / dt if dt > 0 else 0.0
        eta = (self.total - self.done) / rate if rate > 0 else math.nan
        n = 30
        bar = "#" * int(n * self.done / max(self.total, 1))
        msg = (f"{self.label} [{bar:<{n}s}] {self.done}/{self.total} {rate:.2f} points/s "
               f"ETA {eta:5.0f} s failed {self.failed}")
        self.stream.write(("\r" + msg) if self.tty else (msg + "\n"))
        if self.tty and self.done >= self.total:
            self.stream.write("\n")
        self.stream.flush()


