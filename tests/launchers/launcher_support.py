"""Helpers shared by the launcher tests: composing with the ``hydra`` node,
the options the Ray launcher resolves, the job logs of a sweep."""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from sphri.config import CONF_DIR, normalize_overrides, register_schemas

RAY_TARGET = "hydra_plugins.hydra_ray_launcher.ray_launcher.RayLauncher"
SLURM_TARGET = "hydra_plugins.hydra_submitit_launcher.submitit_launcher.SlurmLauncher"
THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS", "SPHRI_THREADS")
SETUP_THREADS = "export OMP_NUM_THREADS=$(( SLURM_CPUS_PER_TASK > 0 ? SLURM_CPUS_PER_TASK : 1 ))"
#: hydra-ray-launcher registers a `hydra/launcher/ray` node of its own; our
#: ray.yaml has the same name, so Hydra merges the two and warns about it.
SCHEMA_MATCH_WARNING = "ignore:(?s).*validated against ConfigStore schema:UserWarning"


def compose_with_hydra(overrides: list[str]) -> DictConfig:
    """The job config with its ``hydra`` node, as ``python -m sphri OVERRIDES`` composes it."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra
    from hydra.core.hydra_config import HydraConfig

    register_schemas()
    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose("config", overrides=normalize_overrides(overrides), return_hydra_config=True)
    HydraConfig.instance().set_config(cfg)  # `${hydra:...}` interpolations resolve
    return cfg


def ray_options(cfg: DictConfig) -> tuple[dict, dict]:
    """(ray.init kwargs, ray.remote options) exactly as the Ray launcher resolves them."""
    ray = cfg.hydra.launcher.ray
    return OmegaConf.to_container(ray.init, resolve=True), OmegaConf.to_container(ray.remote, resolve=True)


def job_logs(output_dir: Path) -> list[str]:
    """Texts of the job logs (``<sweep_dir>/<job>/*.log``) of every sweep under ``output_dir``."""
    return [p.read_text() for p in sorted(output_dir.glob("multirun/*/*/[0-9]*/*.log"))]
