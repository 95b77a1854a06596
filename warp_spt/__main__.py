"""``python -m warp_spt``: the same as the ``warp-spt`` command."""

import sys

from .cli import main

sys.exit(main())
