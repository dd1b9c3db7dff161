"""A lab adds its own encoder, layout and model from its own package, outside sphri:
one module and one YAML each (tests/plugin_example/), nothing changed in sphri."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import forked_cli
import pytest

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = Path(__file__).resolve().parent / "plugin_example"
PLUGIN = ["encoder=nearest", "layout=vertices", "model=centroid"]


@pytest.fixture
def lab(tmp_path) -> Path:
    """The example lab package and its config folder, copied outside the repository."""
    shutil.copytree(EXAMPLE, tmp_path / "lab")
    return tmp_path / "lab"


def _run(lab: Path, *args: str, cwd: Path) -> subprocess.CompletedProcess:
    """``python -m ...`` with the lab's package on ``PYTHONPATH`` (forked: the lab's module is imported in
    the child, from the lab's folder, as in a fresh interpreter)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(lab), str(REPO)])}
    return forked_cli.run(list(args), cwd, env, 600)


def test_user_components_run_end_to_end(lab, tmp_path):
    search = f"hydra.searchpath=[file://{lab / 'conf'}]"
    job = _run(
        lab, "-m", "sphri", "+debug=fast", "plugins=[labext]", search, *PLUGIN, "tracking.enabled=false", cwd=tmp_path
    )
    assert job.returncode == 0, (job.stdout + job.stderr)[-3000:]
    assert "model       NearestCentroid" in job.stdout
    assert "taxels" in job.stdout and "grid" not in job.stdout.split("resolution")[1].split("\n")[0]


def test_user_components_are_refused_unless_their_package_is_listed(lab, tmp_path):
    search = f"hydra.searchpath=[file://{lab / 'conf'}]"
    out = _run(lab, "-m", "sphri", "validate", search, "encoder=nearest", cwd=tmp_path)
    assert out.returncode == 2
    assert "encoder._target_='labext.skin.NearestTaxelEncoder'" in out.stderr and "plugins=[labext]" in out.stderr


@pytest.mark.parametrize(
    "target, message",
    [
        ("labext.skin.VertexLayout", "does not implement the encoder protocol: missing encode"),
        ("labext.skin.NoSuchEncoder", "cannot be imported as a class"),
    ],
)
def test_a_user_class_missing_its_stage_method_fails_at_composition(lab, tmp_path, target, message):
    search = f"hydra.searchpath=[file://{lab / 'conf'}]"
    out = _run(
        lab,
        "-m",
        "sphri",
        "validate",
        "plugins=[labext]",
        search,
        "encoder=nearest",
        f"encoder._target_={target}",
        cwd=tmp_path,
    )
    assert out.returncode == 2 and message in out.stderr, out.stderr[-2000:]
