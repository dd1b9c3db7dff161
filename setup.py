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

from setuptools import find_namespace_packages, setup
from setuptools.command.bdist_wheel import bdist_wheel
from setuptools.command.build_py import build_py


HERE = Path(__file__).resolve().parent
CONF_PACKAGES = ["sphri.conf"] + sorted(
    "sphri.conf." + ".".join(d.relative_to(HERE / "conf").parts)
    for d in (HERE / "conf").rglob("*")
    if d.is_dir() and any(d.glob("*.yaml"))
)



class build_py_with_commit(build_py):
    """Also write ``sphri/_build_info.json`` (the git commit the wheel was built from) into the build:
    an installed wheel has no checkout to ask, and MLflow runs record this commit
    (``sphri.tracking.mlflow_tracker.git_commit``). Not in an editable install (``pip install -e``, as
    ``make install`` does): its build folder holds no package to write into (setuptools printed the
    FileNotFoundError's traceback as a warning), and the checkout answers the commit itself."""

    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):
            return
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
    # Found as namespaces, so that folders without __init__.py are packages too: hydra_plugins (as Hydra's
    # plugin discovery wants; find_packages would skip it and with it sphri's sweeper) and sphri's data-only
    # folders (the reports' Jinja2 templates, the robot descriptions in sphri/robots/data/<robot>/), which
    # setuptools would otherwise ship with a "Package would be ignored" warning.
    packages=find_namespace_packages(include=["sphri", "sphri.*"], exclude=["*.__pycache__"])
    + find_namespace_packages(include=["hydra_plugins.*"])
    + CONF_PACKAGES,
    package_dir={"sphri.conf": "conf"},
    # configs, plus data tables that live beside their code (e.g. sphri/sessions/scenario_priors.yaml),
    # plus the robot descriptions shipped with sphri (sphri/robots/data/reachy2: URDF, PLY meshes, licence)
    package_data={"sphri": ["**/*.yaml", "*.mplstyle", "robots/data/*/*", "robots/data/*/meshes/*"],
                  "sphri.templates": ["*.html.j2"],
                  **{name: ["*.yaml"] for name in CONF_PACKAGES}},
)
