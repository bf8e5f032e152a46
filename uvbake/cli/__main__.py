"""``python -m uvbake.cli``: the ``uvbake`` command."""

import sys

from uvbake.cli import main

sys.exit(main())
