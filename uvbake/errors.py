"""The errors uvbake raises.

Every message names the problem and the way out, in one line, so the CLI can print it as it is.
"""


import re


def in_words(message: str, names: dict[str, str], *, flags: bool = False) -> str:
    """``message`` with the parameters it names (``names``' keys, whole words) called what the user
    called them: other keywords (an adapter's ``size=512`` for ``texture_size_px=512``), or with
    ``flags`` command line flags (``texture_size_px=(2048, 1024)`` -> ``--texture-size 2048x1024``)."""
    if not names:
        return message
    pattern = re.compile(r"\b(" + "|".join(map(re.escape, names)) + r")\b"
                         r"(?:=(\((\d+), (\d+)\)|\[(\d+), (\d+)\]|[^\s,;:)]+))?")

    def swap(m: re.Match) -> str:
        name, value = names[m.group(1)], m.group(2)
        if value is None:
            return name
        if not flags:
            return f"{name}={value}"
        pair = m.group(3) or m.group(5)
        return f"{name} {pair}x{m.group(4) or m.group(6)}" if pair else f"{name} {value}"

    return pattern.sub(swap, message)


class UvbakeError(Exception):
    """Base class of every error uvbake raises on purpose."""


class InputError(UvbakeError, ValueError):
    """The input (mesh, array, option or path) is not usable; the message says how to fix it."""


class ChartError(InputError):
    """A chart is not a valid disk-with-holes; the message names the chart and the fix."""


class NotDiskError(ChartError):
    """A chart is closed or has handles: valid surface, but it must be cut into disks to flatten."""


class SolverError(UvbakeError, RuntimeError):
    """A solver failed on valid input."""


class OutputError(UvbakeError, OSError):
    """An output could not be written (full disk, permissions); the message names the user's path."""


class Cancelled(KeyboardInterrupt):
    """The run was interrupted (SIGINT or SIGTERM); ``signum`` says which.

    A ``KeyboardInterrupt`` subclass, not a :class:`UvbakeError`: the many ``except Exception``
    clauses (ours around third-party readers, libraries' own) must not turn it into an input error.
    """

    def __init__(self, signum=None):
        super().__init__(f"interrupted by signal {signum}" if signum else "interrupted")
        self.signum = signum
