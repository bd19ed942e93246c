"""Progress lines on stderr: which stage the diagnosis is in, and since when."""

import sys
import time

import equinox as eqx


class Progress(eqx.Module):
    """Prints `[diagnose  12.3 s] <message>` to stderr when `enabled`."""

    enabled: bool
    started: float = eqx.field(default_factory=time.perf_counter)

    def say(self, message: str) -> None:
        if self.enabled:
            elapsed = time.perf_counter() - self.started
            print(f"[diagnose {elapsed:6.1f} s] {message}", file=sys.stderr, flush=True)
