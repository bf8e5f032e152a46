"""The ``uvbake`` command: argparse subcommands, one error-to-exit-code map (:mod:`uvbake.cli.common`).

    uvbake MESH [...]           unwrap (the default command; ``uvbake unwrap MESH`` is the same)
    uvbake check PATH [...]     validate the UVs of a textured mesh
    uvbake sweep MESH [...]     alpha sensitivity study
    uvbake batch INPUTS -o DIR  many meshes on Dask

SIGINT and SIGTERM are handled alike from the first line of :func:`main`, before the subcommands'
heavy imports (which is why they are imported inside it): the run stops at the next poll of
:func:`uvbake.cancel.check_cancelled`, temporary files are removed, nothing is written, and the exit
status is 130 or 143; the command line's own process exits within a second whatever it was doing.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys
from types import ModuleType
from typing import Any

from uvbake import cancel
from uvbake.cli.common import ArgumentParser, run

__all__ = ["main", "COMMANDS"]

#: subcommand -> (module with add_arguments and run, one-line help)
COMMANDS = {
    "unwrap": ("uvbake.cli.unwrap", "unwrap a mesh into a textured atlas (the default command)"),
    "check": ("uvbake.cli.check", "validate the UVs of a textured mesh"),
    "sweep": ("uvbake.cli.sweep", "alpha sensitivity study"),
    "batch": ("uvbake.cli.batch", "many meshes on Dask, resumable"),
}
DEFAULT_COMMAND = "unwrap"
#: the usage line of `uvbake --help`: the default command and the subcommands
USAGE = ("uvbake [-h] [--version] MESH [options]   (unwrap; options below)\n"
         "       uvbake {unwrap,check,sweep,batch} ...   (see uvbake COMMAND --help)")
#: Seconds from SIGINT/SIGTERM to the command line process's exit at the latest (the promise is one).
GRACE_S = 0.5


def _module(name: str) -> ModuleType:
    return importlib.import_module(COMMANDS[name][0])


def parser() -> ArgumentParser:
    """``uvbake`` with its subcommands; each subcommand's parser reports usage errors as input errors."""
    unwrap = _module("unwrap")
    p = ArgumentParser(prog="uvbake", description=unwrap.DESCRIPTION, epilog=unwrap.EPILOG,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", metavar="{unwrap,check,sweep,batch}", parser_class=ArgumentParser)
    for name, (_, summary) in COMMANDS.items():
        module = _module(name)
        # `uvbake MESH` is `uvbake unwrap MESH`: its help and errors read as the command itself
        prog = "uvbake" if name == DEFAULT_COMMAND else f"uvbake {name}"
        usage = USAGE if name == DEFAULT_COMMAND else None
        sp = sub.add_parser(name, prog=prog, help=summary, description=getattr(module, "DESCRIPTION", None),
                            usage=usage,
                            epilog=getattr(module, "EPILOG", None),
                            formatter_class=argparse.RawDescriptionHelpFormatter,
                            exit_on_usage_error=name == "batch")
        module.add_arguments(sp)
        sp.set_defaults(run=module.run, prog=prog)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run ``uvbake``; return the exit status (see :mod:`uvbake.cli.common`).

    Called without ``argv`` (the command line), a cancelled run ends the process at once with its
    status, without waiting for worker threads to reach their next poll.
    """
    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    installed = cancel.install_signal_handlers(
        exit_after_s=GRACE_S if argv is None else None,
        message="uvbake: interrupted ({signal}); no output was written")
    try:
        code = _main(list(sys.argv[1:] if argv is None else argv))
        if argv is None and cancel.cancelled_signal() is not None:
            sys.stdout.flush()
            sys.stderr.flush()
            cancel.os_exit(code)
        return code
    finally:
        if installed:
            for sig, handler in previous.items():
                if handler is not None:
                    signal.signal(sig, handler)
        cancel.reset()


def _main(argv: list[str]) -> int:
    if not argv or argv[0] not in COMMANDS:
        argv = [DEFAULT_COMMAND, *argv]          # uvbake MESH ... and uvbake --help
    prog = "uvbake" if argv[0] == DEFAULT_COMMAND else f"uvbake {argv[0]}"

    def command() -> int:
        p = parser()                             # the subcommands' heavy imports happen here
        cancel.check_cancelled()                 # a signal a library's import swallowed stops here
        args: Any = p.parse_args(argv)
        return int(args.run(args))

    return run(prog, command)
