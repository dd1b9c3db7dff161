"""An installed sphri (a built wheel, not the source tree) finds its configs
and runs a job from any working directory."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """Build the wheel (no network, no build isolation) and install it, without
    its dependencies (they are this environment's), into an empty folder."""
    root = tmp_path_factory.mktemp("wheel")
    wheels, target = root / "dist", root / "site"
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation", "-w", str(wheels), str(REPO)],
        capture_output=True, text=True, cwd=root,
    )
    assert build.returncode == 0, build.stderr[-3000:]
    (wheel,) = wheels.glob("sphri-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    shipped = {n for n in names if n.startswith("sphri/conf/") and n.endswith(".yaml")}
    in_repo = {"sphri/conf/" + p.relative_to(REPO / "conf").as_posix() for p in (REPO / "conf").rglob("*.yaml")}
    assert shipped == in_repo, f"configs missing from the wheel: {sorted(in_repo - shipped)[:5]}"
    assert not any(n.startswith(("tests/", "bench/", "conf/")) for n in names)
    install = subprocess.run(
        [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(target), str(wheel)],
        capture_output=True, text=True,
    )
    assert install.returncode == 0, install.stderr[-3000:]
    return target


def _env(site: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(site)  # the installed copy comes first, the source tree is not on the path
    return env


def test_wheel_finds_its_configs_outside_the_repository(installed, tmp_path):
    probe = subprocess.run(
        [sys.executable, "-c", "import sphri, sphri.config as c; print(sphri.__file__); print(c.CONF_DIR)"],
        capture_output=True, text=True, cwd=tmp_path, env=_env(installed),
    )
    assert probe.returncode == 0, probe.stderr[-3000:]
    module_file, conf_dir = probe.stdout.split()
    assert Path(module_file).is_relative_to(installed)
    assert Path(conf_dir) == installed / "sphri" / "conf"


def test_wheel_runs_a_debug_job_from_another_directory(installed, tmp_path):
    job = subprocess.run(
        [sys.executable, "-m", "sphri", "+debug=fast", "tracking.enabled=false"],
        capture_output=True, text=True, cwd=tmp_path, env=_env(installed), timeout=600,
    )
    assert job.returncode == 0, (job.stdout + job.stderr)[-3000:]
    assert "accuracy" in job.stdout
    assert (tmp_path / "outputs" / "cache").is_dir()
