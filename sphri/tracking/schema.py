"""Schema of the ``tracking`` group."""

from __future__ import annotations

from dataclasses import dataclass

from sphri.config import ComponentSchema, require, store


@dataclass
class TrackingSchema(ComponentSchema, group="tracking"):
    """Base of the tracking group's schemas."""


@dataclass
class MlflowTrackingSchema(TrackingSchema):
    """MLflow tracking: one run per job (params, metrics, artifacts), a parent run per sweep."""

    _target_: str = "sphri.tracking.mlflow_tracker.MlflowTracker"
    enabled: bool = True
    """Log each job to MLflow (false: run without tracking)."""
    uri: str | None = None
    """Tracking URI; None = SQLite at ``<output_dir>/mlflow.db`` (absolute path).
    Any MLflow URI works, e.g. ``http://127.0.0.1:5000`` for a local server."""
    experiment: str = "sphri"
    """MLflow experiment name."""
    artifacts: bool = True
    """Log the composed config, per-participant CSV, confusion counts (CSV) and summary files."""
    confusion_png: bool = True
    """With ``artifacts``: also draw the confusion matrix as a PNG, for browsing runs in the MLflow UI
    (its cost a job: docs/BENCHMARKS.md; the sweep report redraws its matrices from the counts either way)."""
    retries: int = 8
    """Retries of a tracking write that hits a locked SQLite database."""
    log_model: bool | None = None
    """Log the job's model, fit once more on every participant, as an MLflow pyfunc model (artifact
    ``model``: ``mlflow.pyfunc.load_model("runs:/<run_id>/model")``, ``skin live model=runs:/...``).
    None (default): for a single job, not for the jobs of a sweep (the refit recomputes the job's
    windows and trains once more: about a third of a Random Forest job's time); true or false: always
    or never."""
    register_model: str | None = None
    """Also register that model under this name in the MLflow model registry (``models:/<name>/<version>``)."""

    def check(self) -> None:
        require(bool(self.experiment.strip()), self.key("experiment"), self.experiment, "must be a non-empty name")
        require(self.retries >= 0, self.key("retries"), self.retries, "must be >= 0")
        name, key = self.register_model, self.key("register_model")
        if name is not None:
            require(bool(name.strip()), key, name, "must be a non-empty model name (or null)")
            require(self.log_model is not False, key, name, "needs tracking.log_model=true (or null)")
        schemes = ("sqlite:///", "http://", "https://", "postgresql", "mysql", "databricks", "file:")
        if self.uri is not None:
            expected = "must be an MLflow tracking URI (sqlite:///ABS.db, http://127.0.0.1:PORT, ...)"
            require(self.uri.startswith(schemes), self.key("uri"), self.uri, expected)


store(group="tracking", name="mlflow_schema", node=MlflowTrackingSchema)
