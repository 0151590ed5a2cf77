"""Stopping a run partway: SIGINT or SIGTERM, deferred to the end of the step, and the data workers' share in it."""

from __future__ import annotations

import signal
import sys
import threading


class Interruption:
    """Ctrl-C (SIGINT) or SIGTERM (a scheduler preempting the job, a `kill`) during training, deferred: the first
    sets `requested`, and the loop writes last/ and stops at the end of its step; a second interrupts at once.
    Installed in the main thread only."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.requested, self.previous = False, {}

    def __enter__(self) -> "Interruption":
        if threading.current_thread() is threading.main_thread():
            self.previous = {s: signal.signal(s, self.handle) for s in self.SIGNALS}
        return self

    def __exit__(self, *exc) -> None:
        for s, handler in self.previous.items():
            signal.signal(s, handler)

    def handle(self, signum, frame) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True
        print(f"\n{signal.Signals(signum).name}: stopping after this step to save last/ (again to stop at once)",
              file=sys.stderr)


def stop_workers(batches) -> None:
    """End a DataLoader iterator's worker processes now, not in the interpreter's exit: a worker ignores SIGTERM
    (ignore_interrupts), so the exit's terminate-and-join of child processes would wait for it forever."""
    if hasattr(batches, "_shutdown_workers"):
        batches._shutdown_workers()


def ignore_interrupts(worker_id: int) -> None:
    """A data worker leaves Ctrl-C and SIGTERM to the training loop (which stops after its step, then ends the
    workers)."""
    for s in Interruption.SIGNALS:
        signal.signal(s, signal.SIG_IGN)
