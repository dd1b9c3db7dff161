"""``python -m sphri.coverage``: where on the robot people touch, per group of trials.

Contact density maps (PNG, PLY, unwrapped map), the coverage curve with a
placement recommendation and an .npz for ``layout=density``, and paired
sliced-Wasserstein tests between groups. See :mod:`sphri.analysis.cli` for
the arguments and :mod:`sphri.analysis` for the library.
"""

from __future__ import annotations

import sys

from sphri.analysis.cli import main

if __name__ == "__main__":
    sys.exit(main())
