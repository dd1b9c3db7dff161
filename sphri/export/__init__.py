"""Model export: model files, the MLflow pyfunc model and training for export.

- :mod:`~sphri.export.registry`: exportable models by ``NAME`` (each saves and loads its own state);
- :mod:`~sphri.export.model_file`: ``.sphrimodel`` files (signed JSON header + npz, no pickle);
- :mod:`~sphri.export.pyfunc_model`: a model file served as an MLflow ``pyfunc`` model;
- :mod:`~sphri.export.train`: fit the configured model on the pipeline's windows and save a model
  file (``sphri export out=m.sphrimodel ...``).
"""

from sphri._lazy import lazy_exports

__getattr__, __all__ = lazy_exports(
    "sphri.export",
    {
        "ModelBundle": "sphri.export.model_file",
        "ModelFileError": "sphri.export.model_file",
        "load_model": "sphri.export.model_file",
        "save_model": "sphri.export.model_file",
        "inspect_model": "sphri.export.model_file",
        "register": "sphri.export.registry",
    },
)
