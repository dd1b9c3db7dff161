"""Data stage: gesture datasets as :class:`sphri.types.GestureDataset`.

Components (``data=...``): :class:`~sphri.data.synthetic.SyntheticData`
(``synthetic``, the default: calibrated synthetic gestures) and
:class:`~sphri.data.vr_gesture.VRGestureData` (``vr_gesture``: the recorded
VR study, parquet + manifests). :func:`~sphri.data.writer.write_dataset`
writes any dataset in the recorded layout; :mod:`sphri.data.stats` compares
contact statistics with published references
(:mod:`sphri.data.reference_stats`). CLIs: ``sphri synthesize``
and ``sphri stats``.
"""

from sphri._lazy import lazy_exports

# Lazy: importing the package (e.g. for its config schema) imports no heavy module.
__getattr__, __all__ = lazy_exports(
    "sphri.data",
    {
        "ManifestError": "sphri.data.format",
        "read_manifest": "sphri.data.format",
        "SyntheticData": "sphri.data.synthetic",
        "DatasetError": "sphri.data.vr_gesture",
        "VRGestureData": "sphri.data.vr_gesture",
        "write_dataset": "sphri.data.writer",
    },
)
