"""Which jobs of a sweep form one curve: the group keys and their labels.

A curve is the jobs that agree on every group key. The keys are the params
that vary across the sweep's own jobs (its parent's children) other than the
resolution (``layout.res``, or ``encoder.res``, the name runs of earlier releases logged it under,
and the derived ``resolution.*``/``meta.*`` params) and the seed (replicates of one point), leaving out the params that
cannot change a result (:func:`sphri.config.result_neutral`: runtime settings
such as ``cv.progress``, ``plugins``, where the job ran): e.g. ``model`` in a
model comparison, ``robot`` in a morphology sweep. A job the sweep skipped
because an earlier job outside it had finished the same config joins the
curve of the point it stands for, whatever it logged besides. ``group_by``
names the keys instead.
"""

from __future__ import annotations

import difflib
from collections.abc import Sequence

from sphri.config import result_neutral, runtime_keys

#: Group keys shown first, in this order, when they vary.
KEY_ORDER = (
    "variant",
    "robot",
    "data",
    "surface",
    "layout",
    "encoder",
    "noise",
    "filter",
    "window",
    "contact",
    "model",
    "cv",
)

#: The param whose values are replicates of one sweep point, not groups (the run's ``seed``).
REPLICATE_KEY = "seed"

#: The resolution's param, then the name runs of earlier releases logged it under (read for one release).
RES_PARAMS = ("layout.res", "encoder.res")


def res_param(params: dict[str, str], default: str | None = None) -> str | None:
    """A job's resolution as logged: :data:`RES_PARAMS`, the first one present, else ``default``."""
    return next((params[k] for k in RES_PARAMS if k in params), default)


#: ``group_by`` value for one curve over every job.
NO_GROUPS = "none"


def _candidates(params: Sequence[dict[str, str]]) -> list[str]:
    return sorted(
        {
            k
            for p in params
            for k in p
            if k not in (*RES_PARAMS, REPLICATE_KEY) and not k.startswith(("resolution.", "meta."))
        }
    )


def varying_params(params: Sequence[dict[str, str]]) -> list[str]:
    """Params with more than one value across ``params``, other than the resolution and the seed."""
    return [k for k in _candidates(params) if len({p.get(k, "") for p in params}) > 1]


def group_keys(params: list[dict[str, str]]) -> list[str]:
    """Params that vary across jobs and can change their results, other than the resolution: the grouping
    of a sweep.

    Component choices (``robot``, ``model``, ...) come first; a setting
    (``model.n_estimators``) is kept only when the chosen components do not
    already determine it.
    """
    if not params:
        return []
    runtime = runtime_keys()
    varying = [k for k in varying_params(params) if not result_neutral(k, runtime)]
    seeds = {p.get(REPLICATE_KEY, "") for p in params}
    if len(seeds) > 1:  # settings the seed alone fixes (model.seed: ${seed}) vary with the replicates, not by group
        by_seed: dict[str, set[str]] = {}
        for k in list(varying):
            by_seed.clear()
            for p in params:
                by_seed.setdefault(p.get(REPLICATE_KEY, ""), set()).add(p.get(k, ""))
            if all(len(v) == 1 for v in by_seed.values()):
                varying.remove(k)
    top = [k for k in varying if "." not in k]
    top.sort(key=lambda k: (KEY_ORDER.index(k) if k in KEY_ORDER else len(KEY_ORDER), k))
    keys: list[str] = []

    def determined(k: str) -> bool:
        """True when the keys kept so far fix ``k`` (e.g. ``variant=coverage`` fixes ``encoder``)."""
        if not keys:
            return False
        by_group: dict[tuple[str, ...], set[str]] = {}
        for p in params:
            by_group.setdefault(tuple(p.get(g, "") for g in keys), set()).add(p.get(k, ""))
        return all(len(v) == 1 for v in by_group.values())

    for k in top + [k for k in varying if "." in k]:
        if not determined(k):
            keys.append(k)
    return keys


def chosen_keys(group_by: Sequence[str], params: Sequence[dict[str, str]]) -> list[str]:
    """The keys ``group_by`` names (``none``: one curve), checked against the params that vary across
    ``params``; a ValueError names the key and the choices."""
    choices = varying_params(params)
    if list(group_by) == [NO_GROUPS]:
        return []
    for key in group_by:
        if key not in choices:
            close = difflib.get_close_matches(key, choices, n=2, cutoff=0.6)
            hint = f" (did you mean {' or '.join(close)}?)" if close else ""
            raise ValueError(
                f"group_by: {key!r} is not a param that varies across this sweep's jobs{hint}; "
                f"choices: {', '.join([*choices, NO_GROUPS])}"
            )
    return list(dict.fromkeys(group_by))


def group_label(values: dict[str, str], model: str) -> str:
    """Readable name of a group: ``rf``, or ``robot=nao_child, model=rf``."""
    if not values or not any(values.values()):
        return model
    if len(values) == 1:
        ((k, v),) = values.items()
        return v if "." not in k else f"{k}={v}"
    return ", ".join(f"{k}={v}" for k, v in values.items())
