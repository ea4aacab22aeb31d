"""Progress of long work that suits where it goes (issue 69): on a terminal one line redrawn in place; in a log
(standard error redirected to a file) a line every LOG_EVERY_S and one at the end, so that a log reads one update a
line instead of one line of carriage returns."""

import sys
import time

LOG_EVERY_S = 5.0


class Counter:
    """`counter(done, total, label)` after each of `total` pieces of work: '  <what> done/total (label)'."""

    def __init__(self, what: str, *, stream=None, every_s: float = LOG_EVERY_S, clock=time.monotonic):
        self.what, self.stream, self.every_s, self.clock = what, stream or sys.stderr, every_s, clock
        self.terminal = bool(getattr(self.stream, "isatty", lambda: False)())
        self.last, self.width, self.open = -float("inf"), 0, False

    def __call__(self, done: int, total: int, label: str = "") -> None:
        text = f"  {self.what} {done}/{total}" + (f" ({label})" if label else "")
        if self.terminal:
            self.width = max(self.width, len(text))
            print("\r" + text.ljust(self.width), end="", file=self.stream, flush=True)
            self.open = done < total
            if not self.open:
                print(file=self.stream, flush=True)
            return
        now = self.clock()
        if done >= total or now - self.last >= self.every_s:
            print(text, file=self.stream, flush=True)
            self.last = now

    def close(self) -> None:
        """End a line left open on a terminal (the work stopped before its last piece)."""
        if self.open:
            print(file=self.stream, flush=True)
            self.open = False
