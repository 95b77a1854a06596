"""``python -m warp_spt.viewer``: the browser viewer (warp_spt.viewer.server.main)."""

import sys

from .server import main

sys.exit(main())
