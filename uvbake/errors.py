"""The errors uvbake raises.

Every message names the problem and the way out, in one line, so the CLI can print it as it is.
"""


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
