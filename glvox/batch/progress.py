"""The progress of a batch on a text stream: a bar on a terminal, plain lines in a log."""

from __future__ import annotations

import sys
import time
from typing import Any, Callable

#: Seconds between progress lines when stderr is not a terminal.
LOG_INTERVAL_S = 10.0


def _hms(seconds: float) -> str:
    s = int(round(seconds))
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}"


class Progress:
    """Progress of a batch on a text stream: a bar with rate and ETA on a
    terminal (redrawn at most 10 times a second), a plain line every
    ``log_interval`` seconds otherwise, nothing when disabled."""

    def __init__(self, total: int, *, stream=None, enabled: bool = True, tty: bool | None = None,
                 log_interval: float = LOG_INTERVAL_S, clock: Callable[[], float] = time.monotonic):
        self.total = total
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled and total > 0
        self.tty = bool(tty if tty is not None else getattr(self.stream, "isatty", lambda: False)())
        self.log_interval = log_interval
        self.clock = clock
        self.t0 = clock()
        self.done = 0
        self.failed = 0
        self._last = self.t0

    def line(self) -> str:
        """``57/200  28% |#####       |  9.8 mesh/s  ETA 0:00:15  2 failed``."""
        elapsed = self.clock() - self.t0
        rate = self.done / elapsed if elapsed > 0 else 0.0
        frac = self.done / self.total if self.total else 1.0
        eta = _hms((self.total - self.done) / rate) if rate > 0 else "?"
        width = 24
        bar = "#" * int(frac * width)
        return (f"{self.done}/{self.total} {frac:4.0%} |{bar:<{width}}| {rate:5.1f} mesh/s  "
                f"ETA {eta}  {self.failed} failed")

    def update(self, row: dict[str, Any]) -> None:
        self.done += 1
        self.failed += row.get("status") == "failed"
        if not self.enabled:
            return
        now = self.clock()
        final = self.done == self.total
        if self.tty and (now - self._last >= 0.1 or final):
            self.stream.write("\r\x1b[2K" + self.line())
            self.stream.flush()
            self._last = now
        elif not self.tty and (now - self._last >= self.log_interval or final):
            self.stream.write(f"[{now - self.t0:8.1f} s] {self.line()}\n")
            self.stream.flush()
            self._last = now

    def close(self) -> None:
        if self.enabled and self.tty:
            self.stream.write("\n")
            self.stream.flush()
