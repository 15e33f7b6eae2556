"""SIGTERM as Ctrl-C: within terminate_as_interrupt() a kill or a batch system's stop raises
KeyboardInterrupt("SIGTERM"), so the CLI and the runner end it as they end Ctrl-C (one line, 130)."""
from __future__ import annotations

import signal
import threading
from contextlib import contextmanager


@contextmanager
def terminate_as_interrupt():
    """Within: SIGTERM raises KeyboardInterrupt("SIGTERM"); the previous handler comes back after
    (a no-op outside the main thread, where signals cannot be set)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum, frame):
        raise KeyboardInterrupt("SIGTERM")

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)
