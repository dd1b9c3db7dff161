"""sphri's sweeper in-process, as ``python -m sphri -m ARGS`` sets it up before its first job: the
jobs a sweep expands to, its fast composer and its validation of every point (used by
test_sweeps_store and test_experiments; no job runs)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from typing import Any


@contextlib.contextmanager
def sweeper(args: Sequence[str]) -> Iterator[tuple[Any, Any, list[list[str]]]]:
    """``(sweeper, Hydra's config loader, every job's overrides)`` for the command-line ``args``."""
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra
    from hydra.types import HydraContext, RunMode
    from omegaconf import OmegaConf

    from hydra_plugins.sphri_sweeper.sphri_sweeper import SphriSweeper
    from sphri.config import CONF_DIR, register_schemas

    register_schemas()
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            loader = GlobalHydra.instance().config_loader()
            base = loader.load_configuration("config", overrides=list(args), run_mode=RunMode.MULTIRUN)
            # Hydra's plugin scan may import basic_sweeper anew, so the class's __init__ (a super() call) is
            # not used here: the attributes it sets are set directly
            found = SphriSweeper.__new__(SphriSweeper)
            found.max_batch_size, found.params = None, OmegaConf.to_container(base.hydra.sweeper.params)
            found.hydra_context = HydraContext(config_loader=loader, callbacks=None)
            found.config = base
            _, jobs = found.job_overrides(list(args))
            yield found, loader, jobs
    finally:
        GlobalHydra.instance().clear()


def hydras_own(found: Any, loader: Any, job: Sequence[str]) -> Any:
    """Hydra's own config for ``job`` of the sweep (``load_sweep_config``), as a plain container without
    its ``hydra`` node: what the sweeper's fast composer must give (compare with :func:`plain_task`)."""
    return plain_task(loader.load_sweep_config(found.config, list(job)))


def plain_task(cfg: Any) -> Any:
    """``cfg`` as a plain container without its ``hydra`` node (the job's own settings)."""
    from omegaconf import OmegaConf

    task = OmegaConf.to_container(cfg)
    task.pop("hydra", None)
    return task
