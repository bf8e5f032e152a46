"""``python -m uvbake``: the ``uvbake`` command."""

import sys

from uvbake.cancel import install_signal_handlers

install_signal_handlers()          # Ctrl-C and SIGTERM cancel cleanly from the very start

from uvbake.cli import main  # noqa: E402  (after the handlers, on purpose)

sys.exit(main())
