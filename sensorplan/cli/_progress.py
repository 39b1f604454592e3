"""Progress lines on stderr: one when a stage starts and, for a stage of repeated units (scenarios, layouts,
replicates), counts with an estimate of the time left.

The computations take a ``progress`` callback and never print; the
commands pass them :meth:`Progress.stage` and :meth:`Progress.count`.
Progress only reads the clock: it changes no number.
"""

import sys
import time

__all__ = ["Progress", "duration"]


def duration(seconds):
    """A duration as a reader wants it: "under 1 s", "12 s", "3 min 05 s"."""
    if seconds < 1.0:
        return "under 1 s"
    if seconds < 60.0:
        return f"{seconds:.0f} s"
    minutes, rest = divmod(int(round(seconds)), 60)
    return f"{minutes} min {rest:02d} s"


class Progress:
    """The progress of one command, printed as ``sensorplan COMMAND: ...`` lines on stderr.

    ``stage(text)`` starts a stage; ``count(done, total)``, the callback of
    a stage's repeated units, prints "done/total, about T left" at most every
    ``interval`` seconds and "total/total in T" at the end.  With ``quiet``
    nothing is printed.
    """

    def __init__(self, command, *, quiet=False, interval=3.0, clock=time.monotonic, stream=None):
        self.command = command
        self.quiet = quiet
        self.interval = interval
        self.clock = clock
        self.stream = stream
        self.started = self.last = clock()
        self.unit = " done"

    def say(self, text):
        if not self.quiet:
            print(f"sensorplan {self.command}: {text}", file=self.stream or sys.stderr, flush=True)

    def stage(self, text, *, unit=""):
        """A stage starts (its counts, of ``unit``, are timed from now)."""
        self.started = self.last = self.clock()
        self.unit = f" {unit}" if unit else " done"
        self.say(text)

    def count(self, done, total):
        """``done`` of the stage's ``total`` units are finished."""
        now = self.clock()
        elapsed = now - self.started
        if done >= total:
            self.say(f"{done}/{total}{self.unit} in {duration(elapsed)}")
        elif done > 0 and now - self.last >= self.interval:
            self.last = now
            self.say(f"{done}/{total}{self.unit}, about {duration(elapsed / done * (total - done))} left")
