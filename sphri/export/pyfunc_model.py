"""A sphri model file served as an MLflow ``pyfunc`` model (MLflow's "models from code").

MLflow's own flavours store a model by pickling it (cloudpickle), which
sphri never loads (``docs/RELIABILITY.md``). This file is the model's code
instead: :func:`sphri.export.train.log_pyfunc_model` logs it as the
``python_model`` with the job's ``.sphrimodel`` file as its one artifact, and
``mlflow.pyfunc.load_model`` runs it, which reads that file through
:func:`sphri.export.model_file.load_model` (skops with trusted types and a
weights-only torch state dict; no pickle anywhere)::

    import mlflow
    model = mlflow.pyfunc.load_model("runs:/<run_id>/model")   # or "models:/<name>/<version>"
    model.predict(windows)   # (n, L, N) float32 windows of taxel readings -> n gesture names
"""

from __future__ import annotations

import mlflow
import numpy as np
from mlflow.pyfunc import PythonModel

#: Name of the sphri model file among the pyfunc model's artifacts.
ARTIFACT = "sphri_model"


class SphriGestureModel(PythonModel):
    """Names the gesture of each window: (n, L, N) float32 taxel readings -> (n,) gesture names."""

    def load_context(self, context) -> None:
        from sphri.export.model_file import load_model

        # the packages the exporting job listed in plugins: a model class of one of them is imported back
        plugins = (getattr(context, "model_config", None) or {}).get("plugins") or ()
        self.bundle = load_model(context.artifacts[ARTIFACT], plugins=[str(x) for x in plugins])

    def predict(self, context, model_input: np.ndarray, params=None) -> np.ndarray:
        x = np.asarray(model_input, dtype=np.float32)
        want = (self.bundle.window_length, self.bundle.n_taxels)
        if x.ndim != 3 or x.shape[1:] != want:
            raise ValueError(
                f"sphri model: windows must be (n, {want[0]}, {want[1]}) (n windows of L frames "
                f"x N taxels); got shape {x.shape}"
            )
        proba = self.bundle.predict_proba(x)
        return np.asarray(self.bundle.labels)[np.argmax(proba, axis=1)]


mlflow.models.set_model(SphriGestureModel())
