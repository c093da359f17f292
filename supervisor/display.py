"""What the supervisor shows: one progress line, messages, the final summary."""
from __future__ import annotations

import math
import os
import sys
import time
from typing import Any, TextIO

NON_TTY_PROGRESS_INTERVAL_S = 5.0


def format_duration(seconds: float) -> str:
    """H:MM:SS."""
    seconds = max(0, int(round(seconds)))
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


def is_number(value: Any) -> bool:
    """A finite int or float (not a bool)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _time_decimals(end_time: Any) -> int:
    """Enough decimals to see simulated time advance: 2 for end times of 1 s and more."""
    if not is_number(end_time) or end_time <= 0:
        return 3
    return max(2, 2 - int(math.floor(math.log10(end_time))))


def format_progress(event: dict, end_time: float | None = None) -> str:
    """`step 1200  t = 3.21 / 20.00 s  dt = 6.1e-04 s  1850 steps/s  ETA 0:00:12` from a progress event."""
    end = event.get("end_time", end_time)
    decimals = _time_decimals(end)
    parts = [f'step {event.get("step", "?")}']
    t = event.get("time")
    if is_number(t):
        if is_number(end):
            parts.append(f"t = {t:.{decimals}f} / {end:.{decimals}f} s")
        else:
            parts.append(f"t = {t:.{decimals}f} s")
    dt = event.get("dt")
    if is_number(dt):
        parts.append(f"dt = {dt:.1e} s")
    rate = event.get("steps_per_second")
    if is_number(rate):
        parts.append(f"{rate:.0f} steps/s" if rate >= 10 else f"{rate:.1f} steps/s")
    eta = event.get("eta_seconds")
    parts.append("ETA " + (format_duration(eta) if is_number(eta) and eta >= 0 else "--"))
    return "  ".join(parts)


def human_size(size: float) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if size < 1000 or unit == "GB":
            return f"{size:.0f} {unit}" if unit == "B" else f"{size:.1f} {unit}"
        size /= 1000.0
    return ""


class Display:
    """The terminal side of a run. On a TTY the progress line is redrawn in place;
    otherwise a progress line is printed every few seconds. Quiet: no progress."""

    def __init__(self, quiet: bool = False, out: TextIO | None = None, err: TextIO | None = None) -> None:
        self.out = out or sys.stdout
        self.err = err or sys.stderr
        self.quiet = quiet
        try:
            self.tty = self.out.isatty()
        except (AttributeError, ValueError):
            self.tty = False
        self._line = ""          # progress line currently shown (TTY)
        self._last_print = None  # monotonic time of the last non-TTY progress print

    def _write(self, stream: TextIO, text: str) -> None:
        try:
            stream.write(text)
            stream.flush()
        except (OSError, ValueError):  # closed or broken pipe: the run goes on regardless
            pass

    def _clear_line(self) -> None:
        if self.tty and self._line:
            self._write(self.out, "\r\x1b[K")

    def _redraw_line(self) -> None:
        if self.tty and self._line:
            self._write(self.out, self._line)

    def progress(self, event: dict, end_time: float | None = None, force: bool = False) -> None:
        if self.quiet:
            return
        line = format_progress(event, end_time)
        if self.tty:
            self._line = line
            self._write(self.out, "\r" + line + "\x1b[K")
            return
        now = time.monotonic()
        if force or self._last_print is None or now - self._last_print >= NON_TTY_PROGRESS_INTERVAL_S:
            self._last_print = now
            self._write(self.out, line + "\n")

    def info(self, text: str) -> None:
        """A line of information (hidden when quiet)."""
        if self.quiet:
            return
        self._clear_line()
        self._write(self.out, text + "\n")
        self._redraw_line()

    def error(self, text: str) -> None:
        """A message on stderr, shown even when quiet. The progress line stays above it, as it was."""
        self.end_progress()
        self._write(self.err, text + "\n")

    def end_progress(self) -> None:
        """Leave the progress line as it is and move below it."""
        if self.tty and self._line:
            self._write(self.out, "\n")
        self._line = ""

    def summary(self, lines: list[str]) -> None:
        self.end_progress()
        self._write(self.out, "".join(line + "\n" for line in lines))


def list_run_folder(run_dir: str) -> list[str]:
    """'name (size)' for each entry of the run folder, sorted; folders as 'name/ (N files)'."""
    entries = []
    try:
        names = sorted(os.listdir(run_dir))
    except OSError:
        return entries
    for name in names:
        path = os.path.join(run_dir, name)
        try:
            if os.path.isdir(path):
                count = sum(len(files) for _, _, files in os.walk(path))
                entries.append(f"{name}/ ({count} files)")
            elif os.path.isfile(path):
                entries.append(f"{name} ({human_size(os.path.getsize(path))})")
        except OSError:
            continue
    return entries


def wrap_items(items: list[str], first_prefix: str, next_prefix: str, width: int = 100) -> list[str]:
    """Lines of comma-separated `items`, never breaking an item."""
    lines, current = [], first_prefix
    for index, item in enumerate(items):
        text = item + ("," if index + 1 < len(items) else "")
        if current not in (first_prefix, next_prefix) and len(current) + 1 + len(text) > width:
            lines.append(current)
            current = next_prefix
        current += ("" if current in (first_prefix, next_prefix) else " ") + text
    lines.append(current)
    return lines
