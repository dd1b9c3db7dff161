"""A lab's own skin components, outside sphri: one module, one YAML each."""

import dataclasses

import numpy as np
from scipy.spatial import cKDTree

from sphri.encode.common import check_frame_index, make_frames, select_rows
from sphri.types import Layout


class NearestTaxelEncoder:
    """Each contact switches on the one taxel nearest to its point (binary)."""

    VERSION = "1"

    def encode(self, contacts, link, surface, layout, frame_index):
        fi = check_frame_index(contacts, frame_index, "encoder=nearest")
        rows, start = select_rows(contacts, fi)
        out = np.zeros((len(fi), layout.n_taxels), dtype=np.uint8)
        if rows.size:
            taxel = cKDTree(layout.position_m).query(np.asarray(contacts.point_m)[rows])[1]
            out[np.repeat(np.arange(len(fi)), np.diff(start)), taxel] = 1
        return make_frames(out, layout, surface)


class VertexLayout:
    """Taxels at res^2 mesh vertices chosen by the seed."""

    VERSION = "1"

    def __init__(self, seed: int = 0):
        self.seed = seed

    def build(self, link, surface, res):
        import trimesh

        mesh = trimesh.Trimesh(link.vertices, link.faces, process=False)
        pick = np.random.default_rng(self.seed).permutation(len(mesh.vertices))[: res * res]
        pos = np.asarray(mesh.vertices[pick], dtype=np.float64)
        spacing = float(np.median(cKDTree(pos).query(pos, k=2)[0][:, 1])) if len(pos) > 1 else 0.01
        return Layout(
            kind="vertices",
            position_m=pos,
            normal=np.asarray(mesh.vertex_normals[pick], dtype=np.float64),
            area_m2=np.full(len(pos), mesh.area / len(pos)),
            uv=None,
            grid_shape=None,
            pitch_u_m=spacing,
            pitch_v_m=spacing,
        )


class NearestCentroid:
    """Nearest class centroid of the time-averaged readings."""

    def __init__(self, geometry=None, shrink: float = 0.0):
        self.geometry = geometry
        self.shrink = shrink

    def fit(self, x, y, groups=None):
        f = np.asarray(x, dtype=np.float64).mean(axis=1)
        self.classes_ = np.unique(y)
        self.centroids_ = np.stack([f[y == c].mean(axis=0) for c in self.classes_])
        return self

    def predict(self, x):
        f = np.asarray(x, dtype=np.float64).mean(axis=1)
        d = ((f[:, None, :] - self.centroids_[None]) ** 2).sum(axis=2)
        return self.classes_[d.argmin(axis=1)]


class DropoutNoise:
    """Each reading reads 0 with probability ``p``, drawn per (seed, trial, frame slot): the same
    draw wherever that slot is computed (offline windows, a streamed skin)."""

    VERSION = "1"

    def __init__(self, p: float = 0.02):
        if not 0.0 <= p < 1.0:
            raise ValueError(f"noise.p={p!r} is invalid: must be in [0, 1)")
        self.p = p

    def apply(self, frames, frame_index, trial_key, seed):
        v = np.asarray(frames.values)
        out = v.copy()
        mask = 0xFFFFFFFFFFFFFFFF
        for i, (slot, key) in enumerate(zip(np.asarray(frame_index), np.asarray(trial_key))):
            rng = np.random.default_rng([int(seed) & mask, int(key) & mask, int(slot) & mask])
            out[i, rng.random(v.shape[1]) < self.p] = 0
        return dataclasses.replace(frames, values=out)
