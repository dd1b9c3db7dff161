"""Moved to :mod:`sphri.export.train`. ``python -m sphri.hardware.train_export ...`` runs the same command,
and this name stays importable: it is the same module object, not a copy."""

import sys

from sphri.export import train as _moved

if __name__ == "__main__":
    sys.exit(_moved.main())
sys.modules[__name__] = _moved
