"""Progress that suits where it goes (issue 69): in a log a line every few seconds and one at the end, never a
carriage return; on a terminal one line redrawn in place, ended at the last update or by close()."""

import io

from rc1_drake.progress import Counter


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_a_log_gets_a_line_every_few_seconds_and_one_at_the_end():
    log, now = io.StringIO(), [0.0]
    count = Counter("ran trials:", stream=log, every_s=5.0, clock=lambda: now[0])
    for done in range(1, 14):  # one update a second
        count(done, 13, f"t{done}")
        now[0] += 1.0
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue()
    assert lines == ["  ran trials: 1/13 (t1)", "  ran trials: 6/13 (t6)", "  ran trials: 11/13 (t11)",
                     "  ran trials: 13/13 (t13)"]  # fmt: skip


def test_a_terminal_gets_one_line_redrawn_in_place():
    screen = Terminal()
    count = Counter("replayed trials:", stream=screen)
    count(1, 3, "a")
    count(2, 3, "bb")
    count.close()  # the work stopped early: the line is ended
    count.close()
    text = screen.getvalue()
    assert text.count("\r") == 2 and text.endswith("\n") and text.count("\n") == 1
    finished = Terminal()
    done = Counter("x", stream=finished)
    done(1, 1)
    done.close()
    assert finished.getvalue() == "\r  x 1/1\n"
