"""Data stage: gesture datasets as :class:`sphri.types.GestureDataset`.

Components (``data=...``): :class:`~sphri.data.synthetic.SyntheticData`
(``synthetic``, the default: calibrated synthetic gestures) and
:class:`~sphri.data.vr_gesture.VRGestureData` (``vr_gesture``: the recorded
VR study, parquet + manifests). :func:`~sphri.data.writer.write_dataset`
writes any dataset in the recorded layout; :mod:`sphri.data.stats` compares
contact statistics with published references
(:mod:`sphri.data.reference_stats`). CLIs: ``python -m sphri.data.synthesize``
and ``python -m sphri.data.stats``.
"""

from sphri.data.format import ManifestError, read_manifest
from sphri.data.synthetic import SyntheticData
from sphri.data.vr_gesture import DatasetError, VRGestureData
from sphri.data.writer import write_dataset

__all__ = ["DatasetError", "ManifestError", "SyntheticData", "VRGestureData", "read_manifest", "write_dataset"]
