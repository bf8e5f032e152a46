"""The ``uvbake`` command: unwrap (default), ``check`` and ``sweep``."""

from uvbake.cli.unwrap import main

__all__ = ["main"]
