"""The ``uvbake`` command: argparse subcommands, one error-to-exit-code map (:mod:`uvbake.cli.common`).

    uvbake MESH [...]           unwrap (the default command; ``uvbake unwrap MESH`` is the same)
    uvbake check PATH [...]     validate the UVs of a textured mesh
    uvbake sweep MESH [...]     alpha sensitivity study
    uvbake batch INPUTS -o DIR  many meshes on Dask
"""

from __future__ import annotations

import argparse
import sys

from uvbake.cli import batch, check, sweep, unwrap
from uvbake.cli.common import ArgumentParser, run

__all__ = ["main", "COMMANDS"]

#: subcommand -> (module with add_arguments and run, one-line help)
COMMANDS = {
    "unwrap": (unwrap, "unwrap a mesh into a textured atlas (the default command)"),
    "check": (check, "validate the UVs of a textured mesh"),
    "sweep": (sweep, "alpha sensitivity study"),
    "batch": (batch, "many meshes on Dask, resumable"),
}
DEFAULT_COMMAND = "unwrap"
#: the usage line of `uvbake --help`: the default command and the subcommands
USAGE = ("uvbake [-h] [--version] MESH [options]   (unwrap; options below)\n"
         "       uvbake {unwrap,check,sweep,batch} ...   (see uvbake COMMAND --help)")


def parser() -> ArgumentParser:
    """``uvbake`` with its subcommands; each subcommand's parser reports usage errors as input errors."""
    p = ArgumentParser(prog="uvbake", description=unwrap.DESCRIPTION, epilog=unwrap.EPILOG,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", metavar="{unwrap,check,sweep,batch}", parser_class=ArgumentParser)
    for name, (module, summary) in COMMANDS.items():
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
    """Run ``uvbake``; return the exit status (see :mod:`uvbake.cli.common`)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in COMMANDS:
        argv = [DEFAULT_COMMAND, *argv]          # uvbake MESH ... and uvbake --help
    p = parser()
    prog = "uvbake" if argv[0] == DEFAULT_COMMAND else f"uvbake {argv[0]}"

    def command() -> int:
        args = p.parse_args(argv)
        return int(args.run(args))

    return run(prog, command)
