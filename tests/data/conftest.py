"""Fixtures of the data stage tests: the study's hand, the parametric Reachy, small datasets."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hydra.utils import instantiate

from sphri.config import component_node
from sphri.types import Contacts, GestureDataset, Robot


def load_component(group: str, name: str, **overrides):
    """Instantiate ``conf/<group>/<name>.yaml`` without composing the whole config."""
    cfg = component_node(group, name)
    for k, v in overrides.items():
        cfg[k] = v
    return instantiate(cfg, _convert_="all")


@pytest.fixture(scope="session")
def hand():
    return load_component("hand", "quest_capsules").build()


@pytest.fixture(scope="session")
def robot() -> Robot:
    return load_component("robot", "reachy").build()


@pytest.fixture(scope="session")
def small(hand, robot) -> GestureDataset:
    """3 participants x 2 repetitions x 8 gestures on arm and torso."""
    from sphri.data.synthetic import SyntheticData

    return SyntheticData(seed=7, participants=3, repetitions=2, regions=["arm", "torso"]).load(hand=hand, robot=robot)


def hand_link_query(dataset: GestureDataset, link, frames: np.ndarray, margin: float = 0.0):
    """Exact query (sphri.contact.capsule_mesh_query) of the hand's capsules in ``frames`` against ``link``;
    row ``i * n_capsules + c`` is capsule c in ``frames[i]``."""
    from sphri.contact import capsule_mesh_query
    from sphri.hand.kinematics import capsule_segments

    p0, p1 = capsule_segments(dataset.poses[frames], dataset.hand)
    radius = np.tile(dataset.hand.radius_m, len(frames))
    return capsule_mesh_query(link.vertices, link.faces, p0.reshape(-1, 3), p1.reshape(-1, 3), radius, margin=margin)


def compute_contacts(dataset: GestureDataset, robot: Robot) -> Contacts:
    """Exact capsule-vs-link contacts (sphri.contact.capsule_mesh_query) as a Contacts table."""
    c = dataset.hand.n_capsules
    region_of_frame = dataset.trials["region"].to_numpy()[dataset.frame_trial_index()]
    parts = []
    for region in np.unique(region_of_frame):
        fr = np.flatnonzero(region_of_frame == region)
        q = hand_link_query(dataset, robot.link_for(str(region)), fr)
        i = np.flatnonzero(q.in_contact)
        parts.append(
            (
                fr[i // c],
                i % c,
                q.distance[i],
                q.inside[i],
                q.point[i],
                q.segment_point[i],
                q.triangle[i],
                q.barycentric[i],
                q.normal[i],
                q.patch_radius[i],
                q.depth[i],
            )
        )
    cols = [np.concatenate(x) for x in zip(*parts)]
    order = np.lexsort((cols[1], cols[0]))
    cols = [x[order] for x in cols]
    return Contacts(dataset.n_frames, cols[0].astype(np.int64), cols[1].astype(np.int16), *cols[2:])


@pytest.fixture(scope="session")
def contacts_of():
    """The :func:`compute_contacts` function, for tests that build their own datasets."""
    return compute_contacts


@pytest.fixture(scope="session")
def hand_query():
    """The :func:`hand_link_query` function."""
    return hand_link_query


@pytest.fixture(scope="session")
def small_contacts(small, robot) -> Contacts:
    return compute_contacts(small, robot)


@pytest.fixture(scope="session")
def written_once(small, robot, tmp_path_factory) -> Path:
    """``small`` written in the recorded layout once (Parquet with zstd: about 0.3 s a write); not to be changed."""
    from sphri.data.writer import write_dataset

    out = tmp_path_factory.mktemp("written") / "ds"
    write_dataset(small, robot, out)
    return out


@pytest.fixture()
def written(tmp_path, written_once) -> Path:
    """``small`` written in the recorded layout under a fresh folder (a copy of :func:`written_once`:
    a test may change or break its files)."""
    import shutil

    return Path(shutil.copytree(written_once, tmp_path / "ds"))
