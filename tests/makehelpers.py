"""What the tests that run ``make`` share."""

from __future__ import annotations

import os

# make as a user types it: the suite itself runs under `make test`, whose MAKELEVEL and MAKEFLAGS
# would make these makes print "Entering directory" lines and inherit its flags
MAKE_ENV = {k: v for k, v in os.environ.items()
            if k not in ("MAKELEVEL", "MAKEFLAGS", "MFLAGS", "MAKEOVERRIDES")}
