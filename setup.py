"""Package list for setuptools (the rest of the metadata is in pyproject.toml).

The wheel ships the repository's top-level ``conf/`` as the package
``sphri.conf`` (its group folders as data-only subpackages): pyproject's
``packages.find`` cannot add packages that live outside ``sphri/``, hence
this file. ``sphri.config.CONF_DIR`` reads ``conf/`` in a checkout and
``sphri/conf`` in an installed wheel.
"""

import json
import shutil
import subprocess
from pathlib import Path

from setuptools import find_namespace_packages, find_packages, setup
from setuptools.command.bdist_wheel import bdist_wheel
from setuptools.command.build_py import build_py


HERE = Path(__file__).resolve().parent
CONF_PACKAGES = ["sphri.conf"] + sorted(
    "sphri.conf." + ".".join(d.relative_to(HERE / "conf").parts)
    for d in (HERE / "conf").rglob("*")
    if d.is_dir() and any(d.glob("*.yaml"))
)
# Data-only folders of robot descriptions shipped with sphri (sphri/robots/data/<robot>/..., URDF, PLY
# meshes, licence): listed as packages, as sphri.templates is, so setuptools ships them without its
# "Package would be ignored" warning for folders Python could import.
ROBOT_DATA_PACKAGES = sorted(
    ".".join(d.relative_to(HERE).parts)
    for d in (HERE / "sphri" / "robots" / "data").rglob("*")
    if d.is_dir() and d.name != "__pycache__" and any(f.is_file() for f in d.iterdir())
)



class build_py_with_commit(build_py):
    """Also write ``sphri/_build_info.json`` (the git commit the wheel was built from) into the build:
    an installed wheel has no checkout to ask, and MLflow runs record this commit
    (``sphri.tracking.mlflow_tracker.git_commit``)."""

    def run(self) -> None:
        super().run()
        try:
            commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10,
                                    cwd=HERE).stdout.strip()
            dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], capture_output=True,
                                   text=True, timeout=10, cwd=HERE).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            commit, dirty = "", ""
        if commit and not self.dry_run:
            target = Path(self.build_lib) / "sphri" / "_build_info.json"
            target.write_text(json.dumps({"git_commit": commit, "dirty": bool(dirty)}) + "\n")


class bdist_wheel_fresh(bdist_wheel):
    """Build every wheel from an empty ``build/lib``: setuptools only adds to it (pypa/setuptools#1871), so a
    module removed or renamed since the last build would still ship (``pip wheel .``, ``pip install .``)."""

    def run(self) -> None:
        lib = Path(self.get_finalized_command("build").build_lib).resolve()
        if not self.skip_build and lib.is_dir() and not HERE.is_relative_to(lib):  # never the source tree
            shutil.rmtree(lib)
        super().run()


setup(
    cmdclass={"build_py": build_py_with_commit, "bdist_wheel": bdist_wheel_fresh},
    # hydra_plugins is a namespace package (no __init__.py, as Hydra's plugin discovery wants):
    # find_packages skips it and with it sphri's sweeper, so it is found as a namespace.
    packages=find_packages(include=["sphri", "sphri.*"])
    + find_namespace_packages(include=["hydra_plugins.*"])
    + ["sphri.templates"]  # the reports' Jinja2 templates (data only, read by sphri.templating)
    + ROBOT_DATA_PACKAGES
    + CONF_PACKAGES,
    package_dir={"sphri.conf": "conf"},
    # configs, plus data tables that live beside their code (e.g. sphri/sessions/scenario_priors.yaml),
    # plus every file of the robot descriptions shipped with sphri
    package_data={"sphri": ["**/*.yaml", "*.mplstyle"],
                  "sphri.templates": ["*.html.j2"],
                  **{name: ["*"] for name in ROBOT_DATA_PACKAGES},
                  **{name: ["*.yaml"] for name in CONF_PACKAGES}},
)
