"""No stage output is NaN or infinite on degenerate input: every surface, layout, encoder and noise kind.

For each degenerate link (:mod:`stress_fixtures`: nearly spherical, very
short, slivers and zero-area triangles, 1000 m from the origin, and the
plain Reachy arm) the contacts of the degenerate hand configurations go
through every surface fit, every layout at res 1 and 6, every encoder and
every noise kind, the window assembly and the Random Forest's features.
Combinations that cannot work (a grid on a chart-less surface, the ellipse
encoder on an irregular layout) must raise a ``ValueError`` saying what is
needed instead.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest
from stress_fixtures import CONFIGS, LINK_NAMES, nonfinite_fields

from sphri.encode.coverage import CoverageEncoder
from sphri.encode.ellipse import EllipseEncoder
from sphri.encode.proximity import ProximityEncoder
from sphri.layout.file import FileLayout
from sphri.layout.grid import GridLayout, HexLayout
from sphri.layout.poisson import DensityLayout, RandomLayout
from sphri.models.features import extract_features
from sphri.noise.components import CrosstalkNoise, DeadTaxelsNoise, GaussianNoise, NoNoise, SaltPepperNoise
from sphri.pipeline import trial_keys
from sphri.surface.box import BoxSurface
from sphri.surface.cylinder import CylinderSurface
from sphri.surface.mesh import MeshSurface
from sphri.surface.meshutil import sample_surface
from sphri.window.onset import OnsetWindow

SURFACES = {"cylinder": CylinderSurface, "box": BoxSurface, "mesh": MeshSurface}
RESOLUTIONS = (1, 6)
GRID_LAYOUTS = ("grid", "hex")


def encoders(res: int) -> dict:
    return {
        "ellipse": EllipseEncoder(),
        "ellipse_fraction": EllipseEncoder(binary=False),
        "coverage": CoverageEncoder(),
        "proximity": ProximityEncoder(),
        "proximity_depth": ProximityEncoder(intensity="depth"),
    }


NOISES = {
    "salt_pepper": SaltPepperNoise(),
    "salt_pepper_flip": SaltPepperNoise(mode="flip", p=0.3),
    "gaussian": GaussianNoise(sigma=0.5),
    "dead_taxels": DeadTaxelsNoise(fraction=0.5, value=1.0),
    "crosstalk": CrosstalkNoise(alpha=0.9),
    "none": NoNoise(),
}


def layouts(tmp_path, contacts, link) -> dict:
    """Every layout component; density and file layouts read files written here."""
    dens = tmp_path / "density.npz"
    np.savez(dens, points_m=contacts.point_m, density=np.linspace(0.0, 1.0, contacts.n_contacts))
    pts, _ = sample_surface(link, 30, 1)
    pts = np.concatenate([pts, pts[:3] + 1e-9])  # near-duplicates to merge
    sensor = tmp_path / "sensor.npz"
    np.savez(sensor, position_m=pts, normal=np.zeros_like(pts))  # zero normals: taken from the mesh
    return {
        "grid": GridLayout(),
        "hex": HexLayout(aspect=0.3),
        "random": RandomLayout(),
        "density": DensityLayout(density_path=str(dens)),
        "file": FileLayout(path=str(sensor)),
    }


def check_values(values: np.ndarray, shape: tuple[int, int], what: str) -> list[str]:
    problems = []
    if values.shape != shape:
        problems.append(f"{what}: shape {values.shape} != {shape}")
    if values.dtype not in (np.uint8, np.float32):
        problems.append(f"{what}: dtype {values.dtype} (uint8 or float32 expected)")
    if values.size:
        if not np.all(np.isfinite(values)):
            problems.append(f"{what}: {int((~np.isfinite(values)).sum())} non-finite readings")
        elif values.min() < 0 or values.max() > 1:
            problems.append(f"{what}: readings outside [0, 1]: {values.min()}..{values.max()}")
    return problems


def check_layout(lay, what: str) -> list[str]:
    problems = [f"{what}: {f} not finite" for f in nonfinite_fields(lay)]
    n = lay.n_taxels
    if n < 1:
        problems.append(f"{what}: no taxels")
    if lay.normal.shape != (n, 3) or not np.allclose(np.linalg.norm(lay.normal, axis=1), 1.0, atol=1e-6):
        problems.append(f"{what}: normals are not unit vectors")
    if lay.area_m2.shape != (n,) or lay.area_m2.min() < 0:
        problems.append(f"{what}: areas negative or misshaped")
    if lay.uv is not None and (lay.uv.min() < 0 or lay.uv.max() > 1):
        problems.append(f"{what}: uv outside [0, 1]")
    if not (lay.pitch_u_m >= 0 and lay.pitch_v_m >= 0):
        problems.append(f"{what}: negative pitch")
    return problems


def test_degenerate_configurations_make_contact(degenerate):
    """The fixtures exercise what they claim: contact in every configuration meant to touch."""
    for name, (ds, _, contacts) in degenerate.items():
        assert not nonfinite_fields(contacts), name
        trial = ds.frame_trial_index()[contacts.frame] % len(CONFIGS)
        per = np.bincount(trial, minlength=len(CONFIGS))
        touched = {c for c, k in zip(CONFIGS, per) if k}
        must = {"vertex_edge", "inside", "seam", "cap_centre", "through", "mixed"}
        assert must <= touched, f"{name}: no contact in {sorted(must - touched)}"
        assert not touched & {"no_contact", "empty"}, name
        inside_trials = set(np.asarray(CONFIGS)[trial[contacts.inside]])
        assert "inside" in inside_trials, name
        assert (contacts.depth_m > 0).all() and (contacts.patch_radius_m >= 0).all(), name


@pytest.mark.parametrize("surface_name", SURFACES)
@pytest.mark.parametrize("link_name", LINK_NAMES)
def test_every_component_stays_finite(link_name, surface_name, degenerate, tmp_path, caplog):
    caplog.set_level(logging.ERROR)  # poor-fit warnings are expected here
    ds, robot, contacts = degenerate[link_name]
    link = robot.link_for("arm")
    surface = SURFACES[surface_name]().fit(link)
    problems = [f"surface: {f} not finite" for f in nonfinite_fields(surface)]
    if surface.has_uv:
        assert surface.metres_per_u > 0 and surface.metres_per_v > 0
    window = OnsetWindow(frames=8, no_contact="keep")
    plan = window.plan(contacts, ds)
    fi = plan.selected_frames()
    tk = trial_keys(ds)[ds.frame_trial_index()[fi]]
    for lname, comp in layouts(tmp_path, contacts, link).items():
        for res in RESOLUTIONS:
            what = f"{link_name}/{surface_name}/{lname}@{res}"
            if lname in GRID_LAYOUTS and not surface.has_uv:
                with pytest.raises(ValueError, match="2-D chart"):
                    comp.build(link, surface, res)
                continue
            lay = comp.build(link, surface, res)
            problems += check_layout(lay, what)
            for ename, enc in encoders(res).items():
                if ename.startswith("ellipse") and lay.grid_shape is None:
                    with pytest.raises(ValueError, match="needs a grid layout"):
                        enc.encode(contacts, link, surface, lay, fi)
                    continue
                frames = enc.encode(contacts, link, surface, lay, fi)
                problems += check_values(frames.values, (len(fi), lay.n_taxels), f"{what}/{ename}")
                # a patch always lights its centre's cell; point-like res-1 taxels may sense nothing
                if (ename.startswith("ellipse") or res > 1) and not frames.values.any():
                    problems.append(f"{what}/{ename}: nothing sensed at all")
                for nname, noise in NOISES.items():
                    out = noise.apply(frames, fi, tk, 7)
                    problems += check_values(out.values, frames.values.shape, f"{what}/{ename}/{nname}")
                windows = window.assemble(NOISES["salt_pepper"].apply(frames, fi, tk, 0), plan, ds, lay, surface)
                feats = extract_features(windows.x, windows.geometry)
                if not np.all(np.isfinite(feats)):
                    problems.append(f"{what}/{ename}: non-finite features")
    assert not problems, "\n".join(problems)
