"""Shared fixtures: ../shared (skipped when absent), temporary output dirs."""

from __future__ import annotations

import os
from pathlib import Path

import forked_cli
import pytest
from hypothesis import settings

REPO = Path(__file__).resolve().parent.parent

# Property tests draw the same examples on every run (`make test`, CI): a red run is reproducible.
# SPHRI_DEEP_TESTS=1 (`make test-all`) explores new random examples, remembered in .hypothesis/.
settings.register_profile("repeatable", derandomize=True, database=None)
settings.register_profile("explore")
settings.load_profile("explore" if os.environ.get("SPHRI_DEEP_TESTS") else "repeatable")
SHARED = Path(os.environ.get("SPHRI_SHARED", REPO.parent / "shared"))


#: The test modules that take longest, run first (longest first). With the Makefile's ``--dist loadscope
#: --no-loadscope-reorder`` the two workers then finish together: xdist's own order (most tests first)
#: left these for last, and one worker ran the last of them alone. Ordered by the module times of a
#: ``--durations=0`` run of the suite (2-core AMD EPYC, 2026-11-26, after the CLI tests moved to
#: ``forked_cli``). Order only: no test depends on it; a module missing here runs after these, in
#: collection order.
HEAVY_FIRST = (
    "tests/test_sweeps_store.py",
    "tests/test_experiments.py",
    "tests/test_packaging.py",
    "tests/report/test_report.py",
    "tests/models/test_cnn_gru.py",
    "tests/test_tracking.py",
    "tests/test_sphri_cli.py",
    "tests/sessions/test_study.py",
    "tests/report/test_report_figures.py",
    "tests/test_fold_resume.py",
    "tests/test_command.py",
    "tests/test_tracking_model.py",
    "tests/test_config.py",
    "tests/test_requirement_map.py",
    "tests/analysis/test_coverage.py",
    "tests/stress/test_cnn_gru_curve_device.py",
    "tests/stress/test_finite_sweep.py",
    "tests/test_runtime_settings.py",
    "tests/test_sensitivity.py",
)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    rank = {module: i for i, module in enumerate(HEAVY_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(rank)))  # stable: a module's own order


def _python(args: list[str], cwd: Path, env: dict[str, str] | None = None, timeout: int = 600):
    """``python <args>`` in ``cwd``, its output captured as text (``-m`` modules in a process forked from
    a server that imported sphri's dependencies once: ``forked_cli``)."""
    return forked_cli.run(args, cwd, env, timeout)


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """The ../shared folder with the real study's assets; skips the test when absent."""
    if not (SHARED / "vr-gesture-dataset").is_dir():
        pytest.skip(f"../shared not present at {SHARED}")
    return SHARED


@pytest.fixture()
def failing_mesh_sweep(tmp_path: Path) -> list[str]:
    """Overrides of a two-job sweep (``-m``, serial launcher) whose second job fails at run time: the robot is
    ``arm.obj`` in ``robot.root={good},{bad}``, the parametric Reachy arm in ``good``, a file that is not a mesh
    in ``bad`` (it passes validation and fails at the robot stage). Add ``output_dir=...`` and run."""
    import trimesh

    from sphri import pipeline
    from sphri.config import compose

    good, bad = tmp_path / "good", tmp_path / "bad"
    good.mkdir()
    bad.mkdir()
    link = pipeline.build(compose(["+debug=fast"]).robot).build().link_for("arm")
    trimesh.Trimesh(link.vertices, link.faces, process=False).export(good / "arm.obj")
    (bad / "arm.obj").write_text("this is not a mesh\n")
    return [
        "-m",
        "+debug=fast",
        "layout.res=2",
        "robot=mesh",
        "robot.links={l_arm: arm.obj}",
        "robot.regions={arm: l_arm}",
        "robot.units=m",
        f"robot.root={good},{bad}",
        "hydra/launcher=serial",
    ]


@pytest.fixture()
def sweep_then_report(tmp_path: Path):
    """``run(sweep_args, n_jobs, report_args)``: ``python -m sphri -m <sweep_args>`` into
    ``tmp_path/outputs/sweep`` (serial launcher), checked to finish all ``n_jobs``, then ``python -m sphri report``
    on it, checked to exit 0; returns ``(sweep_dir, report_process)``."""
    env = {
        **os.environ,
        "PYTHONUNBUFFERED": "1",
        "HYDRA_FULL_ERROR": "1",
        "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]),
    }
    out, sweep = tmp_path / "outputs", tmp_path / "outputs" / "sweep"

    def run(sweep_args: list[str], n_jobs: int, report_args: list[str], timeout: int = 600):
        job = _python(
            [
                "-m",
                "sphri",
                "-m",
                *sweep_args,
                f"output_dir={out}",
                f"hydra.sweep.dir={sweep}",
                "hydra/launcher=serial",
            ],
            tmp_path,
            env,
            timeout,
        )
        assert job.returncode == 0 and f"{n_jobs} of {n_jobs} jobs finished" in job.stdout, job.stderr[-3000:]
        rep = _python(["-m", "sphri", "report", str(sweep), *report_args], tmp_path, env, 300)
        assert rep.returncode == 0, rep.stderr[-3000:]
        return sweep, rep

    return run


@pytest.fixture()
def study_error_line(tmp_path: Path):
    """``run(*overrides)``: ``python -m sphri coverage +experiment=scenario_study <overrides>`` (outputs, runs and
    cache under ``tmp_path``, no tracking), checked to exit 1 with no traceback and exactly one line starting
    with ``sphri``; returns that line."""

    def run(*overrides: str) -> str:
        res = _python(
            [
                "-m",
                "sphri",
                "coverage",
                "+experiment=scenario_study",
                *overrides,
                f"out={tmp_path / 'out'}",
                f"output_dir={tmp_path / 'runs'}",
                f"cache.dir={tmp_path / 'cache'}",
                "tracking.enabled=false",
            ],
            REPO,
        )
        assert res.returncode == 1 and "Traceback" not in res.stderr, res.stderr[-3000:]
        errors = [ln for ln in res.stderr.splitlines() if ln.startswith("sphri")]
        assert len(errors) == 1, res.stderr[-3000:]
        return errors[0]

    return run
