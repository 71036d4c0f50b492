"""Progress lines for Python tools, the same text as src/core/progress.h: on a terminal one line
redrawn in place with count, rate and ETA; otherwise a plain line every `interval` seconds."""
import sys
import time


def format_duration(seconds):
    if seconds is None or seconds != seconds or seconds < 0:
        return "?"
    s = int(round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {(s % 3600) // 60:02d} min"


def format_line(label, done, total, unit, rate, extra=""):
    line = f"{label} {done}"
    line += f"/{total} {unit} ({100.0 * done / total:.1f} %)" if total > 0 else f" {unit}"
    line += f", {format_duration(1.0 / rate)} each" if 0 < rate < 1 else f", {rate:.1f} {unit}/s"
    if 0 < total and done < total:
        line += ", ETA " + (format_duration((total - done) / rate) if rate > 0 else "?")
    if extra:
        line += ", " + extra
    return line


class Progress:
    def __init__(self, label, total, unit, interval=2.0, redraw=0.2, terminal=None, out=None):
        self.out = out or sys.stderr
        self.terminal = self.out.isatty() if terminal is None else terminal
        self.label, self.total, self.unit = label, total, unit
        self.interval = redraw if self.terminal else interval
        self.start = self.last = time.monotonic()
        self.done_at_last = self.done = 0
        self.rate = 0.0
        self.drawn = self.finished = False

    def update(self, done, extra=""):
        self.done = done
        now = time.monotonic()
        since = now - self.last
        if since < self.interval or since <= 0:
            return
        recent = (done - self.done_at_last) / since
        self.rate = 0.7 * self.rate + 0.3 * recent if self.drawn else recent
        self._print(self.rate, extra, False)
        self.last, self.done_at_last = now, done

    def finish(self, extra=""):
        if self.finished:
            return
        elapsed = time.monotonic() - self.start
        self._print(self.done / elapsed if elapsed > 0 else 0.0, extra or f"done in {format_duration(elapsed)}", True)
        self.finished = True

    def _print(self, rate, extra, final):
        line = format_line(self.label, self.done, self.total, self.unit, rate, extra)
        if self.terminal:
            self.out.write("\r\033[K" + line + ("\n" if final else ""))
        else:
            self.out.write(line + "\n")
        self.out.flush()
        self.drawn = True
