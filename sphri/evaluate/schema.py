"""Config schemas of the ``cv`` group (``conf/cv/*.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass

from sphri.config import require, require_range, runtime_setting, store

#: Where folds run: ``local`` (this process, or a loky pool of ``workers``) or ``ray`` (a Ray task each).
BACKENDS = ("local", "ray")


@dataclass
class FoldsSchema:
    """What every cross-validation scheme shares: parallel folds, a fold limit, progress."""

    _target_: str = ""
    workers: int = runtime_setting(1)
    """Folds run in parallel processes (1: in this process)."""
    threads_per_worker: int | None = runtime_setting(None)
    """Threads each fold may use (None: available cores // workers)."""
    max_folds: int | None = None
    """Evaluate only the first k folds (debugging; None: all)."""
    progress: bool = runtime_setting(True)
    """Progress bar over folds (shown only on a terminal)."""
    backend: str = runtime_setting("local")
    """Where folds run: ``local`` (this process, or ``workers`` loky processes) or ``ray`` (a Ray task per
    fold with ``threads_per_worker`` CPUs, default 1: on the Ray launcher's cluster, else a running one, else
    a local instance; docs/CLUSTER.md). Needs the ``ray`` package (the ``cluster`` extra), checked when the
    folds start: a runtime setting composes and hashes the same on a machine without Ray."""

    def __post_init__(self) -> None:
        require(self.backend in BACKENDS, "cv.backend", self.backend, f"must be one of {', '.join(BACKENDS)}")
        require_range("cv.workers", self.workers, lo=1)
        if self.threads_per_worker is not None:
            require_range("cv.threads_per_worker", self.threads_per_worker, lo=1)
        if self.max_folds is not None:
            require_range("cv.max_folds", self.max_folds, lo=1)


@dataclass
class LosoSchema(FoldsSchema):
    """``cv=loso``: leave-one-subject-out over participants."""

    _target_: str = "sphri.evaluate.cv.LeaveOneSubjectOut"
    min_participants: int | None = None
    """Refuse to run on fewer participants with windows (None: run, with a named warning in the summary)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.min_participants is not None:
            require_range("cv.min_participants", self.min_participants, lo=2)


@dataclass
class KFoldSchema(FoldsSchema):
    """``cv=kfold``: stratified k-fold within each participant, pooled (not comparable to LOSO)."""

    _target_: str = "sphri.evaluate.cv.WithinSubjectKFold"
    k: int = 5
    """Number of folds (each participant's trials split k ways, stratified by gesture)."""

    def __post_init__(self) -> None:
        require_range("cv.k", self.k, lo=2)
        super().__post_init__()


store(group="cv", name="loso_schema", node=LosoSchema)
store(group="cv", name="kfold_schema", node=KFoldSchema)
