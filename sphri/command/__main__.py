"""``python -m sphri.command VERB ...``: the ``sphri`` console script, where it is not on the PATH."""

import sys

from sphri.command import main

sys.exit(main())
