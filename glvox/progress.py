"""Progress on stderr, one reporter for every long glvox command (batch, compare, bench).

On a terminal it is tqdm's bar: count, percentage, rate, ETA and the step at
hand, redrawn in place.  Anywhere else (a log file, a pipe, CI) a redrawn bar
is noise, so the same text goes out as a plain line every
:data:`LOG_INTERVAL_S` seconds and once at the end: a log shows that the run
is alive and how far it is.  An ETA that cannot be known yet is ``?``.

:class:`Stages` is the other half: the commands that do one job in a few
stages (``glvox voxelize``, ``ldi``, ``volume``) print each stage with the
time since the start.
"""

from __future__ import annotations

import sys
import time
from typing import Callable, TextIO

from tqdm import tqdm

#: Seconds between progress lines when the stream is not a terminal.
LOG_INTERVAL_S = 10.0

#: The text of the bar and of the plain lines (tqdm's format fields).
BAR_FORMAT = "{n_fmt}/{total_fmt} {percentage:3.0f}% |{bar:24}| {rate_fmt}  ETA {remaining}{postfix}"


def _isatty(stream) -> bool:
    return bool(getattr(stream, "isatty", lambda: False)())


class Progress:
    """Progress of ``total`` items (meshes, cells) on ``stream`` (default stderr).

    Parameters
    ----------
    total : int
        Items to do (nothing is shown while it is 0); it may grow later.
    unit : str
        The items' name in the rate, e.g. ``'mesh'`` gives ``2.50 mesh/s``.
    stream : text stream, optional
    enabled : bool
        False shows nothing (``--quiet``).
    tty : bool, optional
        Draw a bar (True) or write plain lines (False); default: whether
        ``stream`` is a terminal.
    log_interval : float
        Seconds between plain lines.
    clock : callable
        Seconds, monotonic; tests pass a fake one.
    """

    def __init__(self, total: int, *, unit: str = "it", stream: TextIO | None = None, enabled: bool = True,
                 tty: bool | None = None, log_interval: float = LOG_INTERVAL_S,
                 clock: Callable[[], float] = time.monotonic):
        self._total, self.unit = total, " " + unit  # tqdm writes the rate as f"{rate}{unit}/s"
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self.tty = _isatty(self.stream) if tty is None else bool(tty)
        self.log_interval = log_interval
        self.clock = clock
        self.t0 = self._last = clock()
        self.done = 0
        self.note = ""
        self._bar = None

    @property
    def total(self) -> int:
        """Items to do; may grow while running (a later stage adds its items)."""
        return self._total

    @total.setter
    def total(self, value: int) -> None:
        self._total = value
        if self._bar is not None:
            self._bar.total = value
            self._bar.refresh()

    def _shown(self) -> bool:
        """Whether anything is shown; on a terminal the bar starts with the first item or note."""
        if not self.enabled or self._total <= 0:
            return False
        if self.tty and self._bar is None:
            # no monitor thread: a process with a thread forks its batch workers
            # through a forkserver instead (slower, see glvox.batch.pool)
            tqdm.monitor_interval = 0
            self._bar = tqdm(total=self._total, initial=self.done, unit=self.unit, file=self.stream,
                             bar_format=BAR_FORMAT, mininterval=0.1, dynamic_ncols=True, leave=True)
            # the bar's own clock, so that its rate and ETA are the ones line() gives
            self._bar._time = self.clock
            self._bar.start_t = self._bar.last_print_t = self.t0
            if self.note:
                self._bar.set_postfix_str(self.note, refresh=False)
        return True

    def line(self) -> str:
        """``57/200  28% |######       | 9.80 mesh/s  ETA 00:15, the step at hand``."""
        elapsed = self.clock() - self.t0
        return tqdm.format_meter(self.done, self.total, elapsed, unit=self.unit, bar_format=BAR_FORMAT,
                                 postfix=self.note or None, ascii=True)  # logs may not be read as UTF-8

    def update(self, n: int = 1) -> None:
        """``n`` more items are done."""
        self.done += n
        if not self._shown():
            return
        if self._bar is not None:
            self._bar.update(n)
        else:
            self._log(final=self.done >= self._total)

    def status(self, note: str) -> None:
        """Show ``note`` (the step at hand, a count of failures) after the counts."""
        self.note = note
        if not self._shown():
            return
        if self._bar is not None:
            self._bar.set_postfix_str(note, refresh=False)
        else:
            self._log()

    def _log(self, final: bool = False) -> None:
        now = self.clock()
        if final or now - self._last >= self.log_interval:
            self.stream.write(f"[{now - self.t0:8.1f} s] {self.line()}\n")
            self.stream.flush()
            self._last = now

    def close(self) -> None:
        """End the bar's line (a terminal); the plain lines need no end."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class Stages:
    """``say(msg)`` prints ``[   1.23 s] msg`` on stderr (nothing when ``quiet``)."""

    def __init__(self, quiet: bool = False, stream: TextIO | None = None,
                 clock: Callable[[], float] = time.perf_counter):
        self.quiet = quiet
        self.stream = stream
        self.clock = clock
        self.t0 = clock()

    def __call__(self, msg: str) -> None:
        if not self.quiet:
            stream = self.stream if self.stream is not None else sys.stderr
            print(f"[{self.clock() - self.t0:7.2f} s] {msg}", file=stream, flush=True)
