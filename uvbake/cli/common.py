"""What every ``uvbake`` subcommand shares: the argument parser and the one error-to-exit-code map.

Exit codes: 0 success; 1 a failed result (an invalid atlas or check, a solve that failed, backends
that disagree, an output that could not be written); 2 bad input (:class:`uvbake.InputError`, bad
arguments, unreadable paths); 3 a bug; 130 interrupted by SIGINT, 143 by SIGTERM.
Errors print one line, never a traceback (set UVBAKE_DEBUG=1 to see one).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
from collections.abc import Callable
from typing import Any, NoReturn

from uvbake.errors import InputError, UvbakeError, in_words

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT, EXIT_BUG, EXIT_INTERRUPTED = 0, 1, 2, 3, 130  # 143: SIGTERM


class ArgumentParser(argparse.ArgumentParser):
    """argparse whose usage errors are uvbake input errors: one line, exit status 2.

    ``exit_on_usage_error=True`` keeps argparse's own behaviour (usage, SystemExit(2)) for a command
    whose callers expect it (``uvbake batch``).
    """

    def __init__(self, *args: Any, exit_on_usage_error: bool = False, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.exit_on_usage_error = exit_on_usage_error

    def error(self, message: str) -> NoReturn:
        if self.exit_on_usage_error:
            super().error(message)
        raise InputError(f"{message}; see `{self.prog} --help`")


#: The Python parameters whose names the library's errors use, as the commands' flags.
FLAGS = {"texture_size_px": "--texture-size", "gutter_px": "--gutter", "texel_density": "--texel-density",
         "mip_levels": "--mip-levels", "max_stretch": "--max-stretch", "max_charts": "--max-charts",
         "max_iter": "--max-iter", "timeout_per_asset_s": "--timeout-per-asset", "preview_size_px": "--preview-size",
         "auto_cut=False": "--no-auto-cut", "weld=True": "--weld", "materials=False": "--ignore-materials"}


def cli_words(message: str) -> str:
    """A library error in the words a command line user typed: ``texture_size_px=(2048, 1024)`` becomes
    ``--texture-size 2048x1024``, ``gutter_px=4`` ``--gutter 4``, a bare ``gutter_px`` ``--gutter``."""
    return in_words(message, FLAGS, flags=True)


def exit_code(exc: BaseException) -> tuple[int, str]:
    """The exit status of an exception and the words that introduce its one-line message."""
    from uvbake import cancel

    signum = getattr(exc, "signum", None) or cancel.cancelled_signal()
    if isinstance(exc, KeyboardInterrupt) or signum is not None:   # an error caused by the signal is the signal
        signum = signum or signal.SIGINT
        return cancel.exit_code(signum), f"interrupted ({signal.Signals(signum).name}); no output was written"
    if isinstance(exc, InputError):
        return EXIT_BAD_INPUT, f"error: {cli_words(str(exc))}"
    if isinstance(exc, UvbakeError):
        return EXIT_FAILED, f"failed: {exc}"
    if isinstance(exc, OSError):
        from uvbake.io.atomic import write_error

        return EXIT_BAD_INPUT, f"error: {write_error(exc.filename or '?', exc)}"
    return EXIT_BUG, f"internal error: {type(exc).__name__}: {exc} (rerun with UVBAKE_DEBUG=1 and report it)"


def run(prog: str, command: Callable[[], int]) -> int:
    """Run a command; map what it raises to one line on stderr and an exit status."""
    try:
        return command()
    except SystemExit as exc:                     # --help; argparse's own usage errors go on up
        if exc.code in (0, None):
            return EXIT_OK
        raise
    except BaseException as exc:  # noqa: BLE001 - one line, no traceback, whatever went wrong
        if os.environ.get("UVBAKE_DEBUG") and not isinstance(exc, KeyboardInterrupt):
            raise
        code, message = exit_code(exc)
        print(f"{prog}: {message}", file=sys.stderr)
        return code
