"""The cluster launcher configs (conf/hydra/launcher/ray.yaml, slurm.yaml) compose
with the expected fields, and what they hand Ray and SLURM is well-formed."""

from __future__ import annotations

import os
from pathlib import Path

import fake_slurm  # tests/launchers/fake_slurm.py (pytest puts this folder on sys.path)
import pytest
import yaml
from launcher_support import (
    RAY_TARGET,
    SCHEMA_MATCH_WARNING,
    SETUP_THREADS,
    SLURM_TARGET,
    THREAD_VARS,
    compose_with_hydra,
    ray_options,
)
from omegaconf import OmegaConf

pytestmark = pytest.mark.filterwarnings(SCHEMA_MATCH_WARNING)


def test_ray_launcher_defaults(tmp_path: Path):
    cfg = compose_with_hydra(["hydra/launcher=ray", f"output_dir={tmp_path}"])
    assert cfg.hydra.launcher._target_ == RAY_TARGET
    init, remote = ray_options(cfg)
    # a local Ray instance; nothing that ray.init refuses when an address is given
    assert init["address"] is None and init["num_cpus"] is None and init["object_store_memory"] is None
    assert remote["num_cpus"] == 1 and remote["max_calls"] == 1
    env = remote["runtime_env"]["env_vars"]
    assert set(env) == set(THREAD_VARS)
    assert all(v == "1" and isinstance(v, str) for v in env.values()), env


@pytest.mark.parametrize("cpus", [2, 3, 16])
def test_ray_thread_caps_follow_num_cpus(tmp_path: Path, cpus: int):
    cfg = compose_with_hydra(["hydra/launcher=ray", f"hydra.launcher.ray.remote.num_cpus={cpus}"])
    _, remote = ray_options(cfg)
    assert remote["num_cpus"] == cpus
    # Ray wants env_vars as strings: the YAML turns the number into one
    assert remote["runtime_env"]["env_vars"] == {k: str(cpus) for k in THREAD_VARS}


def test_ray_join_cluster_override(tmp_path: Path):
    cfg = compose_with_hydra(["hydra/launcher=ray", "hydra.launcher.ray.init.address=10.0.0.1:6379"])
    init, _ = ray_options(cfg)
    assert init["address"] == "10.0.0.1:6379"
    assert init["object_store_memory"] is None  # ray.init raises when joining a cluster with it set


def test_ray_launcher_instantiates_with_valid_options(ray_plugin, tmp_path: Path):
    import ray
    from hydra.utils import instantiate

    cfg = compose_with_hydra(["hydra/launcher=ray", f"output_dir={tmp_path}"])
    launcher = instantiate(cfg.hydra.launcher)
    assert type(launcher).__name__ == "RayLauncher"
    _, remote = ray_options(cfg)
    # what the launcher hands ray.remote() after instantiation (interpolations resolved once)
    assert OmegaConf.to_container(launcher.ray_cfg.remote, resolve=True) == remote
    ray.remote(**remote)(lambda: None)  # Ray validates the task options here (no cluster needed)
    with pytest.raises(ValueError):
        ray.remote(**{**remote, "num_cpus": -1})(lambda: None)


def test_slurm_config_composes_with_cfg_hydra(run_sphri, tmp_path: Path):
    """Needs no plugin: slurm.yaml lists its fields itself (test_config composes every YAML under `make test`)."""
    proc = run_sphri(
        [
            "hydra/launcher=slurm",
            "hydra.launcher.partition=cpu",
            "hydra.launcher.cpus_per_task=8",
            f"output_dir={tmp_path}",
            "--cfg",
            "hydra",
        ],
        cwd=tmp_path,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    launcher = yaml.safe_load(proc.stdout)["hydra"]["launcher"]
    assert launcher["_target_"] == SLURM_TARGET
    assert launcher["partition"] == "cpu" and launcher["cpus_per_task"] == 8
    assert launcher["timeout_min"] == 120 and launcher["mem_gb"] == 16 and launcher["nodes"] == 1
    assert launcher["tasks_per_node"] == 1 and launcher["array_parallelism"] == 64
    assert launcher["max_num_timeout"] == 0 and launcher["account"] is None
    assert launcher["submitit_folder"] == "${hydra.sweep.dir}/.submitit/%j"
    assert launcher["setup"][0] == SETUP_THREADS
    assert all(v in launcher["setup"][1] for v in THREAD_VARS[1:])
    # a misspelt key is refused, naming it
    bad = run_sphri(
        ["hydra/launcher=slurm", "hydra.launcher.partiton=cpu", "--cfg", "hydra"], cwd=tmp_path, timeout=120
    )
    assert bad.returncode != 0 and "partiton" in bad.stderr


def test_slurm_config_has_exactly_the_plugin_fields(submitit_plugin, tmp_path: Path):
    """slurm.yaml spells out the plugin's `submitit_slurm` fields: none missing, none unknown to it."""
    from hydra_plugins.hydra_submitit_launcher.config import SlurmQueueConf

    cfg = compose_with_hydra(["hydra/launcher=slurm", f"output_dir={tmp_path}"])
    assert set(cfg.hydra.launcher) == set(OmegaConf.structured(SlurmQueueConf))
    merged = OmegaConf.merge(OmegaConf.structured(SlurmQueueConf), cfg.hydra.launcher)  # types check
    assert merged.cpus_per_task == 4 and merged.mem_gb == 16


def test_slurm_parameters_make_a_valid_sbatch_script(submitit_plugin, tmp_path: Path, monkeypatch):
    import submitit
    from hydra.utils import instantiate
    from hydra_plugins.hydra_submitit_launcher.config import BaseQueueConf
    from submitit.slurm.slurm import _make_sbatch_string

    cfg = compose_with_hydra(
        [
            "hydra/launcher=slurm",
            "hydra.launcher.partition=cpu",
            "hydra.launcher.cpus_per_task=6",
            "hydra.launcher.account=lab",
            f"output_dir={tmp_path}",
        ]
    )
    launcher = instantiate(cfg.hydra.launcher)
    params = dict(launcher.params)
    assert params["submitit_folder"].startswith(f"{tmp_path}/multirun/")
    assert params["setup"][0] == SETUP_THREADS  # reaches the shell unchanged
    # the launcher's own mapping of its params onto submitit's executor
    params.pop("submitit_folder")
    params.pop("max_num_timeout")
    base = set(OmegaConf.structured(BaseQueueConf).keys())
    monkeypatch.setenv("PATH", f"{fake_slurm.install(tmp_path / 'bin')}:{os.environ['PATH']}")
    executor = submitit.AutoExecutor(cluster="slurm", folder=tmp_path / "submitit")
    executor.update_parameters(
        **{k if k in base else f"slurm_{k}": v for k, v in params.items()}
    )  # refuses unknown keys
    script = _make_sbatch_string(
        command="python -m submitit.core._submit X", folder=tmp_path, map_count=5, **executor._executor.parameters
    )
    opts = fake_slurm.sbatch_options(script)
    assert opts["partition"] == "cpu" and opts["account"] == "lab" and opts["cpus-per-task"] == "6"
    assert opts["time"] == "120" and opts["mem"] == "16GB" and opts["array"] == "0-4%5"
    setup_at = script.index(SETUP_THREADS)
    assert setup_at < script.index("srun "), "thread caps must be exported before the job starts"


def test_fake_slurm_reads_sbatch_options():
    script = "#!/bin/bash\n#SBATCH --array=0-2%2\n#SBATCH --cpus-per-task=3\n#SBATCH --exclusive\necho hi\n"
    assert fake_slurm.sbatch_options(script) == {"array": "0-2%2", "cpus-per-task": "3", "exclusive": ""}
