"""Moved to :mod:`sphri.export.model_file`. This name stays importable (earlier code, notebooks and MLflow
models logged before the move import it): it is the same module object, not a copy."""

import sys

from sphri.export import model_file as _moved

sys.modules[__name__] = _moved
