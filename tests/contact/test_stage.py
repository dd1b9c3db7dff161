"""The contact components: compute(dataset, robot) -> Contacts, configs and schemas."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import trimesh
from hydra import compose, initialize_config_dir
from hydra.utils import instantiate
from omegaconf import OmegaConf

import sphri.contact.schema  # noqa: F401  (registers the schemas)
from sphri.config import CONF_DIR, ConfigError
from sphri.contact import capsule_mesh_query, sphere_mesh_query
from sphri.contact.exact import ExactContact
from sphri.contact.schema import ExactContactSchema, SphereContactSchema
from sphri.contact.spheres import SphereContact
from sphri.hand.kinematics import capsule_segments
from sphri.testing.contact_reference import arm_stand_in
from sphri.types import TRIAL_COLUMNS, Contacts, GestureDataset, HandModel, Link, Robot


def _hand() -> HandModel:
    return HandModel(
        names=("palm", "index1", "index2", "thumb1"),
        fingers=("palm", "index", "index", "thumb"),
        radius_m=np.array([0.022, 0.010, 0.008, 0.018]),
        height_m=np.array([0.09, 0.058, 0.040, 0.069]),
        axis=np.array([0, 0, 1, 2]),
        center_offset_m=np.array([[0.02, 0.0, 0.0], [0.0, 0.03, 0.0], [0.0, 0.05, 0.01], [-0.02, 0.0, 0.0]]),
    )


def _robot(broken_unused: bool = True) -> Robot:
    v, f = arm_stand_in()
    t = trimesh.creation.torus(major_radius=0.08, minor_radius=0.03)
    links = {
        "l_arm": Link("l_arm", v, f, watertight=False),
        "ring": Link("ring", np.asarray(t.vertices), np.asarray(t.faces), watertight=True),
    }
    regions = {"arm": "l_arm", "torso": "ring"}
    if broken_unused:
        # a link no trial uses: touching it at all would raise (NaN vertices)
        links["head"] = Link("head", np.full((3, 3), np.nan), np.array([[0, 1, 2]]), watertight=False)
        regions["head"] = "head"
    return Robot(name="test", links=links, regions=regions)


def _dataset(n_trials: int = 8, frames: int = 60, seed: int = 0) -> GestureDataset:
    """Hands sweeping past, into and through the links; regions alternate."""
    rng = np.random.default_rng(seed)
    hand = _hand()
    rows, poses = [], []
    start = 0
    for i in range(n_trials):
        region = "arm" if i % 3 != 2 else "torso"
        centre = np.array([0.0, 0.0, -0.36]) if region == "arm" else np.zeros(3)
        a = centre + rng.normal(scale=0.08, size=3)
        b = centre + rng.normal(scale=0.02, size=3)
        path = a + np.linspace(0, 1.6, frames)[:, None] * (b - a)
        pos = path[:, None, :] + rng.normal(scale=0.01, size=(frames, hand.n_capsules, 3))
        q = rng.normal(size=(frames, hand.n_capsules, 4))
        q /= np.linalg.norm(q, axis=-1, keepdims=True)
        poses.append(np.concatenate([pos, q], axis=-1))
        rows.append(("participant_01", region, i + 1, f"{i + 1:04d}_pat", "pat", start, frames))
        start += frames
    trials = pd.DataFrame(rows, columns=list(TRIAL_COLUMNS))
    return GestureDataset(
        name="test",
        synthetic=True,
        hand=hand,
        trials=trials,
        poses=np.concatenate(poses).astype(np.float32),
        frame_rate_hz=30.0,
    )


def _brute_force(ds: GestureDataset, robot: Robot, margin: float = 0.0, k: int = 0):
    """Every (frame, capsule) queried directly, no frame culling."""
    p0, p1 = capsule_segments(ds.poses, ds.hand)
    c = ds.hand.n_capsules
    owner = ds.frame_trial_index()
    rows = []
    for region in ("arm", "torso"):
        link = robot.link_for(region)
        frames = np.flatnonzero(ds.trials["region"].to_numpy()[owner] == region)
        a = p0[frames].reshape(-1, 3)
        b = p1[frames].reshape(-1, 3)
        r = np.tile(ds.hand.radius_m + margin, frames.size)
        q = (
            sphere_mesh_query(link.vertices, link.faces, a, b, r, k=k)
            if k
            else capsule_mesh_query(link.vertices, link.faces, a, b, r)
        )
        hit = np.flatnonzero(q.in_contact)
        rows.append((frames[hit // c], hit % c, q.distance[hit], q.inside[hit], q.depth[hit]))
    fr, cap, d, ins, dep = (np.concatenate(x) for x in zip(*rows))
    o = np.lexsort((cap, fr))
    return fr[o], cap[o], d[o], ins[o], dep[o]


def _check_contacts(con: Contacts, ds: GestureDataset):
    k = con.n_contacts
    assert con.n_frames == ds.n_frames
    assert con.frame.dtype == np.int64 and con.capsule.dtype == np.int16 and con.triangle.dtype == np.int64
    for name, shape in (
        ("distance_m", (k,)),
        ("inside", (k,)),
        ("point_m", (k, 3)),
        ("segment_point_m", (k, 3)),
        ("triangle", (k,)),
        ("barycentric", (k, 3)),
        ("normal", (k, 3)),
        ("patch_radius_m", (k,)),
        ("depth_m", (k,)),
    ):
        assert getattr(con, name).shape == shape, name
    key = con.frame * 1000 + con.capsule
    assert (np.diff(key) > 0).all(), "rows must be sorted by frame then capsule, without duplicates"
    assert (con.depth_m > 0).all() and np.isfinite(con.point_m).all()


def test_exact_matches_brute_force_and_skips_unused_links():
    ds = _dataset()
    robot = _robot()
    con = ExactContact().compute(ds, robot)
    _check_contacts(con, ds)
    fr, cap, d, ins, dep = _brute_force(ds, robot)
    assert con.n_contacts > 100 and con.inside.sum() > 5
    assert np.array_equal(con.frame, fr) and np.array_equal(con.capsule, cap)
    assert np.array_equal(con.distance_m, d) and np.array_equal(con.inside, ins)
    assert np.allclose(con.depth_m, dep)


def test_spheres_match_brute_force():
    ds = _dataset(seed=1)
    robot = _robot()
    con = SphereContact(k=3).compute(ds, robot)
    _check_contacts(con, ds)
    fr, cap, d, ins, _ = _brute_force(ds, robot, k=3)
    assert np.array_equal(con.frame, fr) and np.array_equal(con.capsule, cap)
    assert np.array_equal(con.distance_m, d) and not con.inside.any()


def test_margin_inflates_every_radius():
    ds = _dataset(seed=2)
    robot = _robot()
    con = ExactContact(margin_m=0.01).compute(ds, robot)
    fr, cap, d, _, dep = _brute_force(ds, robot, margin=0.01)
    assert np.array_equal(con.frame, fr) and np.array_equal(con.capsule, cap)
    assert np.allclose(con.depth_m, dep)
    assert con.n_contacts > ExactContact().compute(ds, robot).n_contacts


def test_chunking_changes_nothing():
    ds = _dataset(seed=3)
    robot = _robot()
    a = ExactContact(chunk_frames=7).compute(ds, robot)
    b = ExactContact(chunk_frames=100_000).compute(ds, robot)
    for name in ("frame", "capsule", "distance_m", "inside", "point_m", "triangle", "barycentric", "depth_m"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_no_contact_gives_empty_contacts():
    ds = _dataset(n_trials=2, seed=4)
    ds.poses[..., :3] += 5.0  # every hand far away
    con = ExactContact().compute(ds, _robot())
    assert con.n_contacts == 0 and con.n_frames == ds.n_frames and con.point_m.shape == (0, 3)


def test_bad_datasets_raise_clear_errors():
    ds = _dataset(n_trials=2)
    with pytest.raises(KeyError, match="no skin region 'torso'"):
        ExactContact().compute(_dataset(n_trials=3), Robot("x", {"l_arm": _robot().links["l_arm"]}, {"arm": "l_arm"}))
    bad = GestureDataset(ds.name, True, ds.hand, ds.trials, ds.poses[:, :2], 30.0)
    with pytest.raises(ValueError, match="poses must have shape"):
        ExactContact().compute(bad, _robot())
    t = ds.trials.copy()
    t.loc[1, "n_frames"] = 10_000
    with pytest.raises(ValueError, match="trial row 1 spans frames"):
        ExactContact().compute(GestureDataset(ds.name, True, ds.hand, t, ds.poses, 30.0), _robot())
    p = ds.poses.copy()
    p[70, 2, 3:] = 0.0  # a zero quaternion in frame 70
    with pytest.raises(ValueError, match="global frames 0..119"):
        ExactContact().compute(GestureDataset(ds.name, True, ds.hand, ds.trials, p, 30.0), _robot())
    p = ds.poses.copy()
    p[65, 1, 0] = np.nan  # a lost position in frame 65
    with pytest.raises(ValueError, match=r"NaN/inf positions, e.g. \(frame 65, capsule 1\)"):
        ExactContact().compute(GestureDataset(ds.name, True, ds.hand, ds.trials, p, 30.0), _robot())


def test_component_constructors_check_values():
    with pytest.raises(ValueError, match="contact.margin_m"):
        ExactContact(margin_m=-0.1)
    with pytest.raises(ValueError, match="contact.inside"):
        ExactContact(inside="box")
    with pytest.raises(ValueError, match="contact.k"):
        SphereContact(k=0)


@pytest.mark.parametrize("name, cls", [("exact", ExactContact), ("spheres", SphereContact)])
def test_yaml_composes_and_instantiates(name, cls):
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name=f"contact/{name}")
    OmegaConf.to_object(cfg.contact)  # runs the schema's range checks
    comp = instantiate(cfg.contact)
    assert isinstance(comp, cls) and comp.VERSION == "1"
    con = comp.compute(_dataset(n_trials=2), _robot())
    assert con.n_frames == 120


@pytest.mark.parametrize(
    "schema, field, value, key",
    [
        (ExactContactSchema, "margin_m", -0.01, "contact.margin_m"),
        (ExactContactSchema, "inside", "box", "contact.inside"),
        (ExactContactSchema, "chunk_frames", 0, "contact.chunk_frames"),
        (SphereContactSchema, "k", 0, "contact.k"),
        (SphereContactSchema, "margin_m", 2.0, "contact.margin_m"),
    ],
)
def test_schema_range_checks_name_the_key(schema, field, value, key):
    node = OmegaConf.merge(OmegaConf.structured(schema), {field: value})
    with pytest.raises(ConfigError, match=key):
        OmegaConf.to_object(node)


def test_a_link_past_the_memory_limit_is_refused_before_its_mesh_is_prepared(monkeypatch):
    """A 1.8 M-face mesh ran the contact stage for minutes with no estimate; the faces and the chunk say
    what preparing and querying the link takes before anything is built."""
    from sphri.contact import stage
    from sphri.errors import kind_of

    def never(*args, **kwargs):
        raise AssertionError("the mesh was prepared before the estimate")

    monkeypatch.setattr(stage, "prepare_mesh", never)
    monkeypatch.setenv("SPHRI_MAX_MEMORY_GIB", "0.0001")
    robot, ds = _robot(), _dataset()
    faces = len(robot.link_for("arm").faces)
    with pytest.raises(stage.ContactMemoryError) as refused:
        ExactContact().compute(ds, robot)
    msg = str(refused.value)
    assert f"link 'l_arm' ({faces} mesh faces" in msg and "SPHRI_MAX_MEMORY_GIB=0.0001" in msg, msg
    assert "contact.chunk_frames" in msg and kind_of(refused.value) == "memory error"
    monkeypatch.setenv("SPHRI_MAX_MEMORY_GIB", "1")
    monkeypatch.undo()
    assert ExactContact().compute(ds, robot).n_frames == ds.n_frames  # under the limit: computed


def test_a_large_link_says_when_its_preparation_starts_and_ends(monkeypatch, caplog):
    from sphri.contact import stage

    monkeypatch.setattr(stage, "ANNOUNCE_MIN_FACES", 1)
    caplog.set_level("INFO", logger="sphri.contact.stage")
    ExactContact().compute(_dataset(), _robot())
    assert "contact: preparing link 'l_arm'" in caplog.text and "contact: link 'l_arm' prepared in" in caplog.text
