"""The policy's wall-clock schedule next to a robot: a tick every control period of the monotonic clock, each
tick's lateness kept. Imports nothing beyond the standard library."""

import time


def sleep_until(deadline: float) -> float:
    """Sleeps until `deadline` (s, monotonic clock); returns how late it woke (s)."""
    delay = deadline - time.monotonic()
    if delay > 0:
        time.sleep(delay)
    return time.monotonic() - deadline


class Schedule:
    """Ticks every `period` seconds from `start()`.

    Attributes:
      period: seconds per tick.
      jitter: seconds each tick after the first started after its slot.
    """

    def __init__(self, period: float):
        self.period = period
        self.jitter: list[float] = []
        self._start = 0.0

    def start(self) -> None:
        """Tick 0 starts now."""
        self._start = time.monotonic()
        self.jitter = []

    @property
    def tick(self) -> int:
        """The current tick, from 0."""
        return len(self.jitter)

    @property
    def stamp(self) -> float:
        """When the current tick's slot began (s, monotonic clock)."""
        return self._start + self.tick * self.period

    def wait(self) -> None:
        """Sleeps until the next tick's slot."""
        self.jitter.append(sleep_until(self._start + (self.tick + 1) * self.period))
