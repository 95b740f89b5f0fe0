"""Progress lines for long work that reports as it goes: at most one every few seconds,
and none in its first second, so a run refused at once prints its one error line and
nothing else (``rls scene from-net``'s tiles, ``rls traffic import``'s FCD and objects)."""

import time

EVERY_S = 2.0
QUIET_S = 1.0


class Throttled:
    """``say(text)`` at most every ``every`` seconds, from ``quiet`` seconds after it
    was made; ``final=True`` always says (the end of a stage that has been reported)."""

    def __init__(self, say, every=EVERY_S, quiet=QUIET_S):
        self.say, self.every = say, every
        self.t0 = time.perf_counter()
        self.next = self.t0 + quiet
        self.spoke = False

    def __call__(self, text, final=False):
        now = time.perf_counter()
        if now >= self.next or (final and self.spoke):
            self.next = now + self.every
            self.spoke = True
            self.say(text)

    def elapsed(self):
        return time.perf_counter() - self.t0


def eta(done, total, spent):
    """Seconds left at a constant rate, from ``done`` of ``total`` in ``spent``."""
    return spent / done * (total - done) if done > 0 else float("nan")


def left_text(done, total, spent):
    """", about N s left" from ``done`` of ``total`` in ``spent`` seconds, or "" while
    nothing is done (no rate to go by: never "about nan s left")."""
    return f", about {eta(done, total, spent):.0f} s left" if done > 0 else ""
