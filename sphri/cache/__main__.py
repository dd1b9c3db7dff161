"""``python -m sphri.cache info|clear [STAGE ...]``: the command of :mod:`sphri.cache_cli`.

The command lives in a package ``__main__`` so that the cache module never imports its own command line
(``tests/test_architecture.py``: no import cycle between files)."""

import sys

from sphri.cache_cli import main

sys.exit(main())
