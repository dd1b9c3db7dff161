"""Package list for setuptools (the rest of the metadata is in pyproject.toml).

The wheel ships the repository's top-level ``conf/`` as the package
``sphri.conf`` (its group folders as data-only subpackages): pyproject's
``packages.find`` cannot add packages that live outside ``sphri/``, hence
this file. ``sphri.config.CONF_DIR`` reads ``conf/`` in a checkout and
``sphri/conf`` in an installed wheel.
"""

from pathlib import Path

from setuptools import find_namespace_packages, find_packages, setup

HERE = Path(__file__).resolve().parent
CONF_PACKAGES = ["sphri.conf"] + sorted(
    "sphri.conf." + ".".join(d.relative_to(HERE / "conf").parts)
    for d in (HERE / "conf").rglob("*")
    if d.is_dir() and any(d.glob("*.yaml"))
)

setup(
    # hydra_plugins is a namespace package (no __init__.py, as Hydra's plugin discovery wants):
    # find_packages skips it and with it sphri's sweeper, so it is found as a namespace.
    packages=find_packages(include=["sphri", "sphri.*"])
    + find_namespace_packages(include=["hydra_plugins.*"])
    + CONF_PACKAGES,
    package_dir={"sphri.conf": "conf"},
    # configs, plus data tables that live beside their code (e.g. sphri/sessions/scenario_priors.yaml)
    package_data={"sphri": ["**/*.yaml"], **{name: ["*.yaml"] for name in CONF_PACKAGES}},
)
