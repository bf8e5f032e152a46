"""Cancellation: one process-wide flag, set by SIGINT/SIGTERM, polled by every long loop.

    from uvbake.cancel import check_cancelled
    for chart in charts:
        check_cancelled()          # raises uvbake.errors.Cancelled once a signal arrived

The ``uvbake`` command calls :func:`install_signal_handlers` first thing, before any heavy import.
The handler sets the flag and raises :class:`~uvbake.errors.Cancelled` in the main thread; worker
threads (chart solves) see the flag at their next :func:`check_cancelled` (every solver iteration).
A library that swallows the exception (some wrap optional imports in ``except BaseException``)
cannot swallow the flag: the next poll raises again.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Iterator
from typing import Any

from uvbake.errors import Cancelled

__all__ = ["Cancelled", "cancel", "check_cancelled", "cancelled_signal", "install_signal_handlers",
           "reset", "signals_deferred", "exit_code", "os_exit", "register_temp", "unregister_temp"]

_event = threading.Event()
_signum: list[int | None] = [None]


def cancel(signum: int = signal.SIGINT) -> None:
    """Set the flag (as a signal would)."""
    _signum[0] = signum
    _event.set()


def reset() -> None:
    """Clear the flag and the watchdog (tests, and a library caller that handled a cancellation)."""
    _signum[0] = None
    _event.clear()
    _watchdog.update(after_s=None, message=None)


def is_cancelled() -> bool:
    return _event.is_set()


def cancelled_signal() -> int | None:
    """The signal number that cancelled the run, or None."""
    return _signum[0] if _event.is_set() else None


def check_cancelled() -> None:
    """Raise :class:`Cancelled` if a signal arrived (cheap: one Event test)."""
    if _event.is_set():
        raise Cancelled(_signum[0])


def os_exit(code: int) -> None:
    """End the process now (the command line after a signal: worker threads are not waited for)."""
    os._exit(code)


def exit_code(signum: int | None) -> int:
    """The shell's convention: 128 + signal number (130 for SIGINT, 143 for SIGTERM)."""
    return 128 + int(signum or signal.SIGINT)


_temps: set[str] = set()          # temporary files being written, removed by the watchdog
_watchdog: dict[str, Any] = {"after_s": None, "message": None}


def register_temp(path: str | os.PathLike[str]) -> None:
    """A temporary file that must not outlive a cancelled run (see :func:`install_signal_handlers`)."""
    _temps.add(str(path))


def unregister_temp(path: str | os.PathLike[str]) -> None:
    _temps.discard(str(path))


def _handler(signum, frame):
    first = not _event.is_set()
    cancel(signum)
    if first:                      # a second signal during clean-up must not interrupt the clean-up
        if _watchdog["after_s"] is not None:
            threading.Thread(target=_hard_exit, args=(signum,), daemon=True, name="uvbake-watchdog").start()
        raise Cancelled(signum)


def _hard_exit(signum):
    """The process's last resort: the main thread did not finish within the grace period (it is
    stuck in a long C call, or a library swallowed the exception): remove temporaries and exit."""
    import sys
    import time

    time.sleep(_watchdog["after_s"])
    for path in list(_temps):
        with contextlib.suppress(OSError):
            os.unlink(path)
    if _watchdog["message"]:
        with contextlib.suppress(Exception):
            sys.stderr.write(_watchdog["message"].format(signal=signal.Signals(signum).name) + "\n")
            sys.stderr.flush()
    os._exit(exit_code(signum))


def install_signal_handlers(*, exit_after_s: float | None = None, message: str | None = None) -> bool:
    """SIGINT and SIGTERM both cancel the run; False when not in the main thread (nothing done).

    With ``exit_after_s`` (a command line's process, never a library caller's), a watchdog thread
    ends the process that many seconds after the first signal if it is still running, having
    removed every registered temporary file and printed ``message`` (``{signal}`` is filled in).
    """
    if threading.current_thread() is not threading.main_thread():
        return False
    _watchdog.update(after_s=exit_after_s, message=message)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _handler)
    return True


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold SIGINT/SIGTERM back (they stay pending) while a short all-or-nothing step runs."""
    sigs = {signal.SIGINT, signal.SIGTERM}
    try:
        old = signal.pthread_sigmask(signal.SIG_BLOCK, sigs)
    except (AttributeError, OSError, ValueError):
        old = None
    try:
        yield
    finally:
        if old is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)
