"""An installed sphri (a built wheel, not the source tree) finds its configs
and runs a job from any working directory."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _checkout_copy(dest: Path) -> Path:
    """The checkout's files (tracked, and untracked ones git does not ignore: what ``git status`` sees) in ``dest``."""
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        capture_output=True,
        check=True,
        cwd=REPO,
    ).stdout.decode()
    for name in filter(None, listed.split("\0")):
        if (REPO / name).is_file():  # a tracked file deleted in the working tree is not listed twice
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(REPO / name, dest / name)
    return dest


STALE = "sphri/_stale_probe.py"  # a module that is not in the source: only a stale build/lib has it


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """Build the wheel (no network, no build isolation) as the README does, in a copy of the checkout
    whose ``build/lib`` holds a stale module from an earlier build, and install it, without its
    dependencies (they are this environment's), into an empty folder."""
    root = tmp_path_factory.mktemp("wheel")
    wheels, target, source = root / "dist", root / "site", _checkout_copy(root / "src")
    (source / "build" / "lib" / STALE).parent.mkdir(parents=True)
    (source / "build" / "lib" / STALE).write_text("GONE = True\n")
    git_dir = subprocess.run(["git", "rev-parse", "--absolute-git-dir"], capture_output=True, text=True, cwd=REPO)
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation", "-w", str(wheels), "."],
        capture_output=True,
        text=True,
        cwd=source,
        env={**os.environ, "GIT_DIR": git_dir.stdout.strip(), "GIT_WORK_TREE": str(source)},  # setup.py's commit
    )
    assert build.returncode == 0, build.stderr[-3000:]
    ignored = re.findall(r"Package '([^']+)' is absent from the `packages` configuration", build.stdout + build.stderr)
    assert not ignored, f"setuptools warns that these folders would not be packages: {ignored}"
    (wheel,) = wheels.glob("sphri-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    robot_data = {
        p.relative_to(REPO).as_posix()
        for p in (REPO / "sphri" / "robots" / "data").rglob("*")
        if p.is_file() and "__pycache__" not in p.parts
    }
    assert robot_data and robot_data <= set(names), (
        f"robot descriptions missing from the wheel: {sorted(robot_data - set(names))[:5]}"
    )
    shipped = {n for n in names if n.startswith("sphri/conf/") and n.endswith(".yaml")}
    in_repo = {"sphri/conf/" + p.relative_to(REPO / "conf").as_posix() for p in (REPO / "conf").rglob("*.yaml")}
    assert shipped == in_repo, f"configs missing from the wheel: {sorted(in_repo - shipped)[:5]}"
    templates = {"sphri/templates/" + p.name for p in (REPO / "sphri" / "templates").glob("*.html.j2")}
    assert templates and templates <= set(names), (
        f"report templates missing from the wheel: {sorted(templates - set(names))}"
    )
    assert not any(n.startswith(("tests/", "bench/", "conf/")) for n in names)
    install = subprocess.run(
        [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(target), str(wheel)],
        capture_output=True,
        text=True,
    )
    assert install.returncode == 0, install.stderr[-3000:]
    _reuse_compiled_kernels(target)
    return target


def _reuse_compiled_kernels(site: Path) -> None:
    """Give the installed copy the numba kernels ``sphri warmup`` compiled in the checkout.

    numba keeps a kernel beside its source (``__pycache__/*.nbi``, ``*.nbc``) and trusts it while the
    source file's mtime and size are those it was compiled from. The wheel's modules are the checkout's,
    byte for byte, but pip gives them new mtimes, so the installed copy compiled every kernel again at
    its first job (about 30 CPU-s of the suite's wheel sweep: 49 s against 19-22 s for the same sweep).
    Here each installed module identical to the checkout's takes its mtime, and the kernels are copied
    beside it; numba still checks both (a kernel of a changed module is compiled again, as for a user)."""
    package = REPO / "sphri"
    for compiled in [*package.rglob("__pycache__/*.nbi"), *package.rglob("__pycache__/*.nbc")]:
        dest = site / compiled.relative_to(REPO)
        if dest.parent.parent.is_dir():
            dest.parent.mkdir(exist_ok=True)
            shutil.copy2(compiled, dest)
    for source in package.rglob("*.py"):
        installed = site / source.relative_to(REPO)
        if installed.is_file() and installed.read_bytes() == source.read_bytes():
            stat = source.stat()
            os.utime(installed, ns=(stat.st_atime_ns, stat.st_mtime_ns))


def _env(site: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(site)  # the installed copy comes first, the source tree is not on the path
    return env


def test_wheel_finds_its_configs_outside_the_repository(installed, tmp_path):
    code = "import sphri, sphri.config as c; print(sphri.__file__); print(c.CONF_DIR)"
    module_file, conf_dir = _probe(installed, tmp_path, code).split()
    assert Path(module_file).is_relative_to(installed)
    assert Path(conf_dir) == installed / "sphri" / "conf"


def _sphri(site: Path, cwd: Path, *args: str, timeout: int = 600) -> subprocess.CompletedProcess:
    """``python -m <args>`` with only the installed wheel on the path, from ``cwd``."""
    return subprocess.run(
        [sys.executable, "-m", *args], capture_output=True, text=True, cwd=cwd, env=_env(site), timeout=timeout
    )


def _probe(site: Path, cwd: Path, code: str) -> str:
    """The standard output of ``python -c <code>`` with only the installed wheel on the path, from ``cwd``
    (the test fails with its standard error when it exits non-zero)."""
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=cwd, env=_env(site), timeout=600
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout


@pytest.fixture(scope="module")
def wheel_sweep(installed, tmp_path_factory) -> Path:
    """A sweep from the wheel, in a folder outside the repository (its sweeper is a namespace package
    that setup.py once left out: every sweep ended in "Unknown plugin class
    'hydra_plugins.sphri_sweeper...'"); its job keeps its cache in that folder. One point, through the
    default (joblib) launcher: the sweeper, the launcher and the job are what a second point would
    test again."""
    cwd = tmp_path_factory.mktemp("wheel_sweep")
    sweep = _sphri(installed, cwd, "sphri", "-m", "+debug=fast", "layout.res=2", "hydra.sweep.dir=sweep")
    assert sweep.returncode == 0, (sweep.stdout + sweep.stderr)[-3000:]
    assert "1 of 1 jobs finished" in sweep.stdout and "accuracy" in sweep.stdout, sweep.stdout[-2000:]
    assert (cwd / "outputs" / "cache").is_dir()
    return cwd / "sweep"


def test_wheel_leaves_out_a_stale_build_lib(installed):
    """setuptools only adds to ``build/lib``: without setup.py emptying it first, the module planted
    there (as a build before its removal or renaming would leave it) ships in the wheel."""
    assert (installed / "sphri" / "config.py").is_file()
    assert not (installed / STALE).exists()


def test_wheel_ships_the_sweeper(installed):
    assert (installed / "hydra_plugins" / "sphri_sweeper" / "sphri_sweeper.py").is_file()


def test_wheel_sweep_then_its_report(installed, wheel_sweep):
    report = _sphri(installed, wheel_sweep.parent, "sphri", "report", str(wheel_sweep), "formats=png")
    assert report.returncode == 0, (report.stdout + report.stderr)[-3000:]
    assert (wheel_sweep / "report" / "report.html").is_file()


def test_wheel_validates_a_sweep_as_a_checkout_does(installed, tmp_path):
    check = _sphri(installed, tmp_path, "sphri", "validate", "-m", "layout.res=0,4,18")
    assert check.returncode == 2, (check.stdout + check.stderr)[-3000:]
    assert "1 of 3 points fail validation" in check.stderr and "layout.res=0" in check.stderr
    assert "Traceback" not in check.stderr


def test_wheel_cli_show_returns(installed, tmp_path):
    show = _sphri(installed, tmp_path, "sphri", "show", timeout=120)
    assert show.returncode == 0, show.stderr[-3000:]
    assert "hand: HandCapsules" in show.stdout and max(map(len, show.stdout.splitlines())) <= 100


def test_wheel_console_script_completes_from_its_configs(installed, tmp_path):
    """The wheel's ``sphri`` script (sphri.completion) answers a TAB from the wheel's own configs, twice
    (the second from its kept answer), and dispatches ``sphri help`` and ``sphri list robot``."""
    script = installed / "bin" / "sphri"
    assert script.is_file(), (
        sorted(p.name for p in (installed / "bin").iterdir()) if (installed / "bin").is_dir() else []
    )
    env = {**_env(installed), "COMP_LINE": "sphri encoder=", "XDG_CACHE_HOME": str(tmp_path / "xdg")}
    for _ in range(2):
        tab = subprocess.run(
            [sys.executable, str(script), "-sc", "query=bash"],
            capture_output=True,
            text=True,
            env=env,
            cwd=tmp_path,
            timeout=120,
        )
        assert tab.returncode == 0, tab.stderr[-3000:]
        assert tab.stdout.split() == ["encoder=coverage", "encoder=ellipse", "encoder=proximity"], tab.stdout
    assert len(list((tmp_path / "xdg" / "sphri" / "completion").iterdir())) == 1
    # the same script dispatches verbs (sphri.command ships in the wheel): its list, and one verb run for real
    verbs = subprocess.run(
        [sys.executable, str(script), "help"], capture_output=True, text=True, env=_env(installed), cwd=tmp_path
    )
    assert verbs.returncode == 0 and "  report " in verbs.stdout and "  validate " in verbs.stdout, verbs.stderr
    groups = subprocess.run(
        [sys.executable, str(script), "list", "robot"],
        capture_output=True,
        text=True,
        env=_env(installed),
        cwd=tmp_path,
    )
    assert groups.returncode == 0 and "  reachy2 " in groups.stdout, groups.stderr[-3000:]


@pytest.mark.slow  # `make test-all`: the study's code and data are tested from the checkout (tests/sessions) and
# its packaged data from the wheel (test_wheel_builds_the_packaged_reachy2_from_its_own_data) in `make test`
def test_wheel_runs_the_scenario_study_at_debug_size(installed, tmp_path):
    study = _sphri(
        installed,
        tmp_path,
        "sphri",
        "coverage",
        "+experiment=scenario_study",
        "+debug=fast",
        "out=study",
        "experiment.scenario_study.figure_formats=[png]",
        "experiment.scenario_study.view_faces=3000",
    )
    assert study.returncode == 0, (study.stdout + study.stderr)[-3000:]
    assert (tmp_path / "study" / "report.html").is_file()


@pytest.mark.slow  # `make test-all`: export and live from the checkout in `make test` (tests/hardware/test_hw_plugin_model.py)
def test_wheel_exports_a_model_and_runs_skin_live_on_the_simulator(installed, tmp_path):
    small = ["+debug=fast", "data.participants=1", "data.repetitions=1"]
    export = _sphri(installed, tmp_path, "sphri", "export", "out=m.sphrimodel", *small, "model.n_jobs=1")
    assert export.returncode == 0, (export.stdout + export.stderr)[-3000:]
    link = tmp_path / "skin.tty"
    sim = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "sphri",
            "simulate",
            "skin",
            *small,
            f"link={link}",
            "realtime=false",
            "hold_s=60",
        ],
        cwd=tmp_path,
        env=_env(installed),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        import time

        for _ in range(600):  # the simulator builds its stream, then opens the link
            if link.exists() or sim.poll() is not None:
                break
            time.sleep(0.1)
        assert link.exists(), sim.communicate(timeout=30)[0][-3000:]
        live = _sphri(
            installed,
            tmp_path,
            "sphri",
            "skin",
            "live",
            f"port={link}",
            "model=m.sphrimodel",
            "idle_s=3",
            "show=off",
            "out=pred.jsonl",
            timeout=300,
        )
    finally:
        sim.terminate()
        sim.wait(30)
    assert live.returncode == 0, (live.stdout + live.stderr)[-3000:]
    assert "predictions" in live.stdout and (tmp_path / "pred.jsonl").stat().st_size > 0


TUTORIAL = REPO / "docs" / "tutorials" / "from-vr-logs.md"


def bash_blocks(markdown: str) -> list[str]:
    """The bodies of a page's ```bash blocks, in order (other fences, ``` or ```text, are not commands)."""
    return re.findall(r"^```bash\n(.*?)^```[ \t]*$", markdown, flags=re.M | re.S)


def test_bash_blocks_are_the_fenced_bash_commands_only():
    page = "# t\n\n```bash\nsphri a\n```\n\n```\nsphri not-run\n```\n\ntext\n```bash\nx \\\n  y\n```\n"
    assert bash_blocks(page) == ["sphri a\n", "x \\\n  y\n"]
    assert bash_blocks("no commands here\n```\nsphri b\n```\n") == []


def test_wheel_runs_the_vr_logs_tutorial_as_written(installed, tmp_path):
    """docs/tutorials/from-vr-logs.md's ```bash blocks, one bash script (-e, pipefail) in an empty folder, with the
    wheel's ``sphri`` first on the PATH and only the wheel on the Python path: every step exits 0 and leaves
    what the page says it does."""
    blocks = bash_blocks(TUTORIAL.read_text())
    assert len(blocks) >= 9, f"{TUTORIAL} has {len(blocks)} ```bash blocks: the tutorial's commands are missing"
    commands = [line.split()[0] for b in blocks for line in b.splitlines() if line.strip()]
    assert "python" not in commands, "the tutorial spells every command `sphri VERB`"
    env = _env(installed)
    env["PATH"] = f"{installed / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    script = 'set -euo pipefail\n[ "$(command -v sphri)" = "$SPHRI_WHEEL_BIN/sphri" ]\n' + "\n".join(blocks)
    env["SPHRI_WHEEL_BIN"] = str(installed / "bin")
    done = subprocess.run(["bash", "-c", script], capture_output=True, text=True, cwd=tmp_path, env=env, timeout=600)
    out = done.stdout + done.stderr
    assert done.returncode == 0, out[-4000:]
    root = tmp_path / "vr-skin"
    manifest = (root / "logs" / "manifest.csv").read_text().splitlines()
    assert (root / "logs" / "README.txt").read_text().startswith("SYNTHETIC") and len(manifest) == 1 + 24
    assert re.search(r"^mydata: gesture trials, .* 3 participant\(s\), 24 trials, ", done.stdout, re.M), out[-4000:]
    assert re.search(r"A taxel pitch of at most \d+(\.\d+)? mm", done.stdout), done.stdout[-4000:]
    assert (root / "sweep" / "report" / "report.html").is_file()
    assert (root / "coverage" / "recommendation.txt").is_file() and (root / "robot_parts.png").is_file()
    assert (root / "coding" / "coding_sheet.html").stat().st_size > 0
    codes = (root / "coding" / "codes.csv").read_text().splitlines()
    assert len(codes) > 1 and codes[0].endswith(",gesture,coder"), codes[:2]
    assert (root / "arm.sphrimodel").stat().st_size > 0


def test_wheel_knows_the_commit_it_was_built_from(installed, tmp_path):
    """No checkout beside an installed wheel: MLflow runs record the commit setup.py wrote into it."""
    commit = _probe(installed, tmp_path, "from sphri.tracking.mlflow_tracker import git_commit; print(git_commit())")
    head = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, cwd=REPO).stdout.strip()
    assert commit.strip().removesuffix("+dirty") == head


def test_wheel_builds_the_packaged_reachy2_from_its_own_data(installed, tmp_path):
    """robot=reachy2 reads its derivative (URDF, PLY meshes, licence) from the installed package, not from a checkout."""
    data = installed / "sphri" / "robots" / "data" / "reachy2"
    assert (
        (data / "LICENSE").is_file()
        and (data / "SOURCE.md").is_file()
        and len(list((data / "meshes").glob("*.ply"))) == 10
    )
    code = (
        "from hydra.utils import instantiate; from sphri.config import compose; "
        "r = instantiate(compose(['robot=reachy2']).robot).build(); "
        "print(len(r.tree.links), len(r.skipped), r.links['head'].faces.shape[0])"
    )
    assert _probe(installed, tmp_path, code).split() == ["18", "78", "414"]


def test_editable_install_builds_without_a_setuptools_warning(tmp_path):
    """``make install`` is ``pip install -e``: setuptools builds an editable wheel (PEP 660), running
    setup.py's build_py in a build folder that holds no package. Writing the commit there raised, and
    setuptools printed that FileNotFoundError's traceback as a "Customization incompatible with editable
    install" warning to every new user. Built here with setuptools' own PEP 660 hook, no network."""
    source = _checkout_copy(tmp_path / "src")
    git_dir = subprocess.run(["git", "rev-parse", "--absolute-git-dir"], capture_output=True, text=True, cwd=REPO)
    hook = "import sys; from setuptools import build_meta; print(build_meta.build_editable(sys.argv[1]))"
    build = subprocess.run(
        [sys.executable, "-c", hook, str(tmp_path / "dist")],
        capture_output=True,
        text=True,
        cwd=source,
        env={**os.environ, "GIT_DIR": git_dir.stdout.strip(), "GIT_WORK_TREE": str(source)},
        timeout=600,
    )
    assert build.returncode == 0, build.stderr[-3000:]
    wheel = tmp_path / "dist" / build.stdout.strip().splitlines()[-1]
    assert wheel.is_file() and "editable" in wheel.name
    output = build.stdout + build.stderr
    assert "Traceback" not in output and "Customization incompatible" not in output, output[-3000:]
