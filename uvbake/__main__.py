"""``python -m uvbake``: the ``uvbake`` command."""

import sys

from uvbake.cli.unwrap import main

sys.exit(main())
