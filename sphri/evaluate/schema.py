"""Config schemas of the ``cv`` group (``conf/cv/*.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass

from sphri.config import ComponentSchema, setting, store

#: Where folds run: ``local`` (this process, or a loky pool of ``workers``) or ``ray`` (a Ray task each).
BACKENDS = ("local", "ray")


@dataclass
class CvSchema(ComponentSchema, group="cv"):
    """Base of the cv group's schemas."""


@dataclass
class FoldsSchema(CvSchema):
    """What every cross-validation scheme shares: parallel folds, a fold limit, progress."""

    _target_: str = ""
    workers: int = setting(1, runtime=True, lo=1)
    """Folds run in parallel processes (1: in this process)."""
    threads_per_worker: int | None = setting(None, runtime=True, lo=1, optional=True)
    """Threads each fold may use (None: available cores // workers)."""
    max_folds: int | None = setting(None, lo=1, optional=True)
    """Evaluate only the first k folds (debugging; None: all)."""
    progress: bool = setting(True, runtime=True)
    """Progress bar over folds (shown only on a terminal)."""
    backend: str = setting("local", runtime=True, choices=BACKENDS)
    """Where folds run: ``local`` (this process, or ``workers`` loky processes) or ``ray`` (a Ray task per
    fold with ``threads_per_worker`` CPUs, default 1: on the Ray launcher's cluster, else a running one, else
    a local instance; docs/CLUSTER.md). Needs the ``ray`` package (the ``cluster`` extra), checked when the
    folds start: a runtime setting composes and hashes the same on a machine without Ray."""


@dataclass
class LosoSchema(FoldsSchema):
    """``cv=loso``: leave-one-subject-out over participants."""

    _target_: str = "sphri.evaluate.cv.LeaveOneSubjectOut"
    min_participants: int | None = setting(None, lo=2, optional=True)
    """Refuse to run on fewer participants with windows (None: run, with a named warning in the summary)."""


@dataclass
class KFoldSchema(FoldsSchema):
    """``cv=kfold``: stratified k-fold within each participant, pooled (not comparable to LOSO)."""

    _target_: str = "sphri.evaluate.cv.WithinSubjectKFold"
    k: int = setting(5, lo=2)
    """Number of folds (each participant's trials split k ways, stratified by gesture)."""


store(group="cv", name="loso_schema", node=LosoSchema)
store(group="cv", name="kfold_schema", node=KFoldSchema)
