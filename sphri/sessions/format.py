"""Interaction sessions: the in-memory :class:`SessionDataset` and its on-disk format.

A *session* is one free interaction of one participant with the whole robot
in one scenario and repetition: both hands' capsule poses and every robot
link's pose, all in the world frame, at a fixed frame rate. It extends the
VR gesture dataset's layout (:mod:`sphri.data.format`)::

    ROOT/
      sessions.json                          dataset header: format, name, synthetic, robot, links, hands, hand capsules
      participant_XX/manifest.json           one entry per session: scenario, repetition, order, start_position,
                                             frame_rate_hz, n_frames, file
      participant_XX/<scenario>.parquet      one row per (repetition, frame)

Parquet columns: ``repetition`` (int), ``frame`` (int, 0-based within the
session), then for each hand ``h`` and capsule ``c`` ``h/c_pos_x ...
h/c_rot_w`` (metres, unit quaternion xyzw, world frame) and for each link
``link/<name>_pos_x ... _rot_w`` (the link frame's pose in the world). Columns and fields are
listed once in :mod:`sphri.data.recording_schema` (``docs/RECORDING_FORMAT.md``).

:func:`write_sessions` writes it, :class:`SessionData` (``data=sessions``)
reads it back and validates every file; each defect raises
:class:`SessionFormatError` naming the file and the field. Among them: a
``file`` that is absolute or leaves its participant's folder (``../``), a
``frame_rate_hz`` outside [1, 1000] Hz or not finite, a ``frame`` column that
does not run 0..n-1, positions in mm, and two participant ids holding
near-identical sessions (:mod:`sphri.data.duplicates`; ``data.duplicates``).
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sphri.data import recording_schema as schema
from sphri.data.duplicates import DUPLICATE_POLICIES, describe, find_duplicates, fingerprint
from sphri.data.format import POSE_SUFFIXES, participant_id, pose_columns
from sphri.errors import read_json
from sphri.types import HandModel

log = logging.getLogger(__name__)

FORMAT = schema.SESSION_FORMAT
FORMAT_VERSION = schema.SESSION_FORMAT_VERSION
HANDS: tuple[str, ...] = schema.HANDS
#: Columns of :attr:`SessionDataset.sessions`, in order.
SESSION_COLUMNS: tuple[str, ...] = (
    "participant",
    "scenario",
    "repetition",
    "order",
    "start_position",
    "start",
    "n_frames",
)
MANIFEST_SESSION_KEYS: tuple[str, ...] = schema.required(schema.SESSION_MANIFEST)
HEADER_KEYS: tuple[str, ...] = schema.required(schema.SESSION_HEADER)
#: The per-row columns before the pose columns, in order.
ROW_COLUMNS: tuple[str, ...] = schema.names(schema.SESSION_COLUMNS)


#: Sessions are in metres: a median hand or link position farther than this from the origin is refused.
MAX_MEDIAN_DISTANCE_M = 20.0
#: Plausible frame rates of a manifest's ``frame_rate_hz`` (Hz), as for the VR gesture manifests.
MIN_RATE_HZ, MAX_RATE_HZ = 1.0, 1000.0


class SessionFormatError(ValueError):
    """A session file is malformed; the message names the file and the field."""


@dataclass
class _Participant:
    """One participant's sessions as :meth:`SessionData.load_participant` reads them (or several's, joined)."""

    records: list[dict] = field(default_factory=list)
    hands: list[np.ndarray] = field(default_factory=list)
    link_poses: list[np.ndarray] = field(default_factory=list)
    prints: list = field(default_factory=list)
    rates: set[float] = field(default_factory=set)


@dataclass
class SessionDataset:
    """Sessions of free interaction with a whole robot, all frames concatenated (world frame).

    ``hand_poses[start:start + n_frames]`` is one session.
    """

    name: str
    synthetic: bool
    hand: HandModel
    sessions: pd.DataFrame
    """One row per session, columns :data:`SESSION_COLUMNS`."""
    hand_poses: np.ndarray
    """(F, 2, C, 7) float32: per hand (:data:`HANDS`), capsule joint position (m) and quaternion xyzw, world frame."""
    links: tuple[str, ...]
    link_poses: np.ndarray
    """(F, L, 7) float32: each link frame's position (m) and quaternion xyzw in the world."""
    frame_rate_hz: float
    robot: str = ""
    truth: pd.DataFrame | None = None
    """Generator-side labels of a synthetic dataset (scenario prior draws), None when recorded."""

    @property
    def n_frames(self) -> int:
        return int(self.hand_poses.shape[0])

    def frame_session_index(self) -> np.ndarray:
        """(F,) int64 session row owning each frame."""
        counts = self.sessions["n_frames"].to_numpy(dtype=np.int64)
        return np.repeat(np.arange(len(counts), dtype=np.int64), counts)


def make_sessions_frame(records: Sequence[dict]) -> pd.DataFrame:
    df = pd.DataFrame.from_records(list(records), columns=list(SESSION_COLUMNS))
    for col in ("participant", "scenario", "start_position"):
        df[col] = df[col].astype(object)
    for col in ("repetition", "order", "start", "n_frames"):
        df[col] = df[col].astype(np.int64)
    return df.reset_index(drop=True)


def hand_columns(hand: HandModel) -> list[str]:
    return [f"{h}/{c}" for h in HANDS for c in pose_columns(hand.names)]


def link_columns(links: Sequence[str]) -> list[str]:
    return [f"link/{c}" for c in pose_columns(links)]


def write_sessions(ds: SessionDataset, out: str | Path) -> list[Path]:
    """Write ``ds`` in the session format under ``out``; returns the files written."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    header = {
        "format": FORMAT,
        "version": FORMAT_VERSION,
        "name": ds.name,
        "synthetic": bool(ds.synthetic),
        "robot": ds.robot,
        "links": list(ds.links),
        "hands": list(HANDS),
        "hand": {
            "names": list(ds.hand.names),
            "fingers": list(ds.hand.fingers),
            "radius_m": ds.hand.radius_m.tolist(),
            "height_m": ds.hand.height_m.tolist(),
            "axis": ds.hand.axis.tolist(),
            "center_offset_m": ds.hand.center_offset_m.tolist(),
        },
        "frame_rate_hz": float(ds.frame_rate_hz),
    }
    files = [out / "sessions.json"]
    files[0].write_text(json.dumps(header, indent=1) + "\n")
    hcols, lcols = hand_columns(ds.hand), link_columns(ds.links)
    c = ds.hand.n_capsules
    for pid, rows in ds.sessions.groupby("participant", sort=True):
        pdir = out / str(pid)
        pdir.mkdir(exist_ok=True)
        entries = []
        for scen, srows in rows.groupby("scenario", sort=True):
            parts = []
            fname = f"{scen}.parquet"
            for r in srows.itertuples(index=False):
                sl = slice(int(r.start), int(r.start) + int(r.n_frames))
                h = ds.hand_poses[sl].reshape(int(r.n_frames), 2 * c * 7)
                lk = ds.link_poses[sl].reshape(int(r.n_frames), len(ds.links) * 7)
                df = pd.DataFrame(np.concatenate([h, lk], axis=1), columns=hcols + lcols)
                df.insert(0, "frame", np.arange(int(r.n_frames), dtype=np.int32))
                df.insert(0, "repetition", np.full(int(r.n_frames), int(r.repetition), dtype=np.int16))
                parts.append(df)
                entries.append(
                    {
                        "scenario": str(scen),
                        "repetition": int(r.repetition),
                        "order": int(r.order),
                        "start_position": str(r.start_position),
                        "frame_rate_hz": float(ds.frame_rate_hz),
                        "n_frames": int(r.n_frames),
                        "file": fname,
                    }
                )
            pd.concat(parts, ignore_index=True).to_parquet(pdir / fname, index=False, write_page_checksum=True)
            files.append(pdir / fname)
        entries.sort(key=lambda e: (e["order"], e["repetition"]))
        (pdir / "manifest.json").write_text(json.dumps({"participant": str(pid), "sessions": entries}, indent=1) + "\n")
        files.append(pdir / "manifest.json")
    if ds.truth is not None:
        ds.truth.to_csv(out / "generator_truth.csv", index=False)
        files.append(out / "generator_truth.csv")
    return files


def _read_json(path: Path, what: str) -> dict:
    return read_json(path, SessionFormatError, f"{path}: {what} not found", SessionFormatError, obj=True)


def read_header(root: Path) -> dict:
    path = root / "sessions.json"
    h = _read_json(path, "the dataset header (sessions.json)")
    missing = [k for k in HEADER_KEYS if k not in h]
    if missing:
        raise SessionFormatError(f"{path}: missing field(s) {missing}")
    if h["format"] != FORMAT:
        raise SessionFormatError(f"{path}: field 'format' is {h['format']!r}, expected {FORMAT!r}")
    if h["version"] != FORMAT_VERSION:
        raise SessionFormatError(
            f"{path}: field 'version' is {h['version']!r}; this sphri reads version {FORMAT_VERSION}"
        )
    if list(h["hands"]) != list(HANDS):
        raise SessionFormatError(f"{path}: field 'hands' is {h['hands']!r}, expected {list(HANDS)}")
    if (
        not isinstance(h["links"], list)
        or not h["links"]
        or not all(isinstance(x, str) and x for x in h["links"])
        or len(set(h["links"])) != len(h["links"])
    ):
        raise SessionFormatError(f"{path}: field 'links' must be a non-empty list of unique link names")
    try:
        hd = h["hand"]
        hand = HandModel(
            names=tuple(hd["names"]),
            fingers=tuple(hd["fingers"]),
            radius_m=np.asarray(hd["radius_m"], float),
            height_m=np.asarray(hd["height_m"], float),
            axis=np.asarray(hd["axis"], np.int64),
            center_offset_m=np.asarray(hd["center_offset_m"], float).reshape(-1, 3),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise SessionFormatError(f"{path}: field 'hand' is malformed ({exc})") from None
    n = len(hand.names)
    if not (
        len(hand.fingers) == n
        and hand.radius_m.shape == (n,)
        and hand.height_m.shape == (n,)
        and hand.axis.shape == (n,)
        and hand.center_offset_m.shape == (n, 3)
    ):
        raise SessionFormatError(f"{path}: field 'hand': per-capsule arrays must all have {n} entries")
    h["hand_model"] = hand
    return h


def read_manifest(path: Path) -> list[dict]:
    m = _read_json(path, "the participant manifest")
    if "sessions" not in m or not isinstance(m["sessions"], list):
        raise SessionFormatError(f"{path}: missing field 'sessions' (a list)")
    seen = set()
    for i, e in enumerate(m["sessions"]):
        if not isinstance(e, dict):
            raise SessionFormatError(f"{path}: sessions[{i}] must be an object")
        missing = [k for k in MANIFEST_SESSION_KEYS if k not in e]
        if missing:
            raise SessionFormatError(f"{path}: sessions[{i}] is missing field(s) {missing}")
        for k in ("scenario", "start_position"):
            if not isinstance(e[k], str) or not e[k]:
                raise SessionFormatError(f"{path}: sessions[{i}].{k}={e[k]!r} is invalid: a non-empty name")
        for k in ("repetition", "order", "n_frames"):
            if not isinstance(e[k], int) or isinstance(e[k], bool) or e[k] < (0 if k == "order" else 1):
                raise SessionFormatError(f"{path}: sessions[{i}].{k}={e[k]!r} is invalid: a positive integer")
        rate = e["frame_rate_hz"]
        if (
            isinstance(rate, bool)
            or not isinstance(rate, (int, float))
            or not math.isfinite(rate)
            or not MIN_RATE_HZ <= rate <= MAX_RATE_HZ
        ):
            raise SessionFormatError(
                f"{path}: sessions[{i}].frame_rate_hz={rate!r} is implausible: must be a number "
                f"in [{MIN_RATE_HZ:g}, {MAX_RATE_HZ:g}] Hz"
            )
        f = e["file"]
        if not isinstance(f, str) or not f or Path(f).is_absolute() or ".." in Path(f).parts:
            raise SessionFormatError(
                f"{path}: sessions[{i}].file={f!r} is invalid: a file name inside the "
                "participant's folder (no absolute path, no '..')"
            )
        key = (e["scenario"], e["repetition"])
        if key in seen:
            raise SessionFormatError(f"{path}: sessions[{i}]: scenario {key[0]!r} repetition {key[1]} is listed twice")
        seen.add(key)
    return m["sessions"]


class SessionData:
    """``data=sessions``: recorded (or synthesized) sessions from ``root`` (see module docstring).

    ``participants``: how many (None: all, sorted); ``scenarios``: which
    (None: all). ``load`` validates every file it reads.
    """

    VERSION = "1"
    USES_ROBOT = False

    def __init__(
        self,
        root: str | None = None,
        participants: int | None = None,
        repetitions: int | None = None,
        scenarios: Sequence[str] | None = None,
        quat_tolerance: float = 1e-3,
        duplicates: str = "refuse",
        **_: Any,
    ):
        if not root:
            raise ValueError("data.root is empty: set it to a sessions folder (one holding sessions.json)")
        self.root = str(root)
        self.participants = participants
        self.repetitions = repetitions
        self.scenarios = None if scenarios is None else [str(s) for s in scenarios]
        self.quat_tolerance = float(quat_tolerance)
        if duplicates not in DUPLICATE_POLICIES:
            raise SessionFormatError(
                f"data.duplicates={duplicates!r} is invalid: allowed values: {list(DUPLICATE_POLICIES)}"
            )
        self.duplicates = duplicates

    def load(self, hand: HandModel | None = None, robot: Any = None) -> SessionDataset:
        root = Path(self.root)
        if not root.is_dir():
            raise SessionFormatError(f"data.root={self.root!r}: no such folder")
        header = read_header(root)
        shand: HandModel = header["hand_model"]
        if hand is not None and tuple(hand.names) != tuple(shand.names):
            raise SessionFormatError(
                f"{root / 'sessions.json'}: field 'hand' has capsules {list(shand.names)[:3]}..., "
                f"but the configured hand has {list(hand.names)[:3]}..."
            )
        links = list(header["links"])
        if robot is not None:
            missing = [ln for ln in links if ln not in robot.links]
            if missing:
                raise SessionFormatError(
                    f"{root / 'sessions.json'}: field 'links' names {missing}, which robot {robot.name!r} does not have"
                )
        pids = sorted(p.name for p in root.iterdir() if p.is_dir() and (p / "manifest.json").is_file())
        if not pids:
            raise SessionFormatError(f"{root}: no participant folder with a manifest.json")
        if self.participants is not None:
            pids = pids[: int(self.participants)]
        got = _Participant()
        for pid in pids:
            part = self.load_participant(root, pid, shand, links, sum(r["n_frames"] for r in got.records))
            got.records += part.records
            got.hands += part.hands
            got.link_poses += part.link_poses
            got.prints += part.prints
            got.rates |= part.rates
        for pair in find_duplicates(got.prints):
            if self.duplicates == "refuse":
                raise SessionFormatError(
                    f"{root}: {describe(pair, 'sessions')}: a copied participant folder? "
                    "Remove one, or set data.duplicates=warn to load both"
                )
            log.warning(
                "%s: duplicate_participants: %s: both loaded (data.duplicates=warn); they are not independent people",
                root,
                describe(pair, "sessions"),
            )
        if not got.records:
            raise SessionFormatError(f"{root}: no session left after selecting participants/scenarios/repetitions")
        if robot is not None:
            absent = [ln for ln in robot.links if ln not in links]
            if absent:
                log.warning(
                    "%s: robot %r links %s have no poses in these sessions: no contact can be found on them",
                    root / "sessions.json",
                    robot.name,
                    absent,
                )
        if len(got.rates) != 1:
            raise SessionFormatError(f"{root}: manifests mix frame rates {sorted(got.rates)}; one rate per dataset")
        truth = None
        tpath = root / "generator_truth.csv"
        if header["synthetic"] and tpath.is_file():
            truth = pd.read_csv(tpath)
        return SessionDataset(
            name=str(header["name"]),
            synthetic=bool(header["synthetic"]),
            hand=shand,
            sessions=make_sessions_frame(got.records),
            hand_poses=np.concatenate(got.hands),
            links=tuple(links),
            link_poses=np.concatenate(got.link_poses),
            frame_rate_hz=got.rates.pop(),
            robot=str(header["robot"]),
            truth=truth,
        )

    def load_participant(
        self, root: Path, pid: str, shand: HandModel, links: Sequence[str], start: int = 0
    ) -> _Participant:
        """One participant's selected sessions, every file validated (:class:`SessionFormatError` naming the file
        and field); frames are numbered from ``start``."""
        hcols, lcols = hand_columns(shand), link_columns(links)
        c, nl = len(shand.names), len(links)
        got = _Participant()
        mpath = root / pid / "manifest.json"
        entries = read_manifest(mpath)
        named = {str(e["file"]) for e in entries}
        unnamed = sorted(p.name for p in (root / pid).glob("*.parquet") if p.name not in named)
        if unnamed:  # an entry lost from the manifest: its recording would be dropped without a word
            log.warning(
                "%s: %d session file(s) in %s are not named by the manifest and are not read: %s",
                mpath,
                len(unnamed),
                root / pid,
                ", ".join(unnamed[:5]),
            )
        if self.scenarios is not None:
            entries = [e for e in entries if e["scenario"] in self.scenarios]
        if self.repetitions is not None:
            entries = [e for e in entries if e["repetition"] <= int(self.repetitions)]
        tables: dict[str, pd.DataFrame] = {}
        for e in entries:
            ppath = root / pid / str(e["file"])
            inside = (root / pid).resolve()
            if inside not in ppath.resolve().parents:
                raise SessionFormatError(
                    f"{mpath}: field file={e['file']!r} of scenario {e['scenario']!r} "
                    f"repetition {e['repetition']} resolves outside {root / pid} (a link?)"
                )
            if e["file"] not in tables:
                tables[e["file"]] = self._read_table(ppath, hcols, lcols)
            tab = tables[e["file"]]
            rows = tab[tab["repetition"].to_numpy() == e["repetition"]]
            if len(rows) != e["n_frames"]:
                raise SessionFormatError(
                    f"{ppath}: repetition {e['repetition']} has {len(rows)} rows but "
                    f"{mpath} field n_frames says {e['n_frames']}"
                )
            fr = rows["frame"].to_numpy()
            if not np.array_equal(fr, np.arange(len(fr))):
                raise SessionFormatError(
                    f"{ppath}: column 'frame' of repetition {e['repetition']} must run 0..{len(fr) - 1}"
                )
            h = rows[hcols].to_numpy(np.float32).reshape(len(rows), 2, c, 7)
            lk = rows[lcols].to_numpy(np.float32).reshape(len(rows), nl, 7)
            self._check_values(ppath, e, h, lk, hcols, lcols)
            self._check_units(ppath, e, h, lk)
            got.hands.append(h)
            got.link_poses.append(lk)
            if self.duplicates != "off":
                got.prints.append((pid, (str(e["scenario"]), len(h)), fingerprint(h)))
            got.rates.add(float(e["frame_rate_hz"]))
            got.records.append(
                dict(
                    participant=pid,
                    scenario=str(e["scenario"]),
                    repetition=int(e["repetition"]),
                    order=int(e["order"]),
                    start_position=str(e["start_position"]),
                    start=start,
                    n_frames=int(e["n_frames"]),
                )
            )
            start += int(e["n_frames"])
        return got

    @staticmethod
    def _check_units(path: Path, e: dict, h: np.ndarray, lk: np.ndarray) -> None:
        """Positions are metres: a session whose median hand or link position lies more than
        :data:`MAX_MEDIAN_DISTANCE_M` from the origin is in millimetres (or centimetres), and refused."""
        for what, pos in (("hand", h[..., :3]), ("link", lk[..., :3])):
            med = float(np.median(np.linalg.norm(pos.reshape(-1, 3).astype(np.float64), axis=1))) if pos.size else 0.0
            if med > MAX_MEDIAN_DISTANCE_M:
                raise SessionFormatError(
                    f"{path}: repetition {e['repetition']}: {what} positions lie {med:.4g} from the origin (median); "
                    f"sessions are in metres (more than {MAX_MEDIAN_DISTANCE_M:g} m: millimetres or centimetres?)"
                )

    @staticmethod
    def _read_table(path: Path, hcols: list[str], lcols: list[str]) -> pd.DataFrame:
        import pyarrow as pa
        import pyarrow.parquet as pq

        if not path.is_file():
            raise SessionFormatError(f"{path}: parquet file named by the manifest not found")
        try:
            schema = pq.read_schema(path)
        except (pa.ArrowInvalid, OSError) as exc:
            raise SessionFormatError(f"{path}: not a readable parquet file ({exc})") from None
        need = list(ROW_COLUMNS) + hcols + lcols
        missing = [col for col in need if col not in schema.names]
        if missing:
            raise SessionFormatError(f"{path}: missing column(s) {missing[:5]}" + (" ..." if len(missing) > 5 else ""))
        for col in need[len(ROW_COLUMNS) :]:
            if not pa.types.is_floating(schema.field(col).type):
                raise SessionFormatError(f"{path}: column {col!r} has type {schema.field(col).type}, expected float")
        try:
            return pq.read_table(path, columns=need, page_checksum_verification=True).to_pandas()
        except (pa.ArrowInvalid, OSError) as exc:
            raise SessionFormatError(f"{path}: cannot read ({exc})") from None

    def _check_values(
        self, path: Path, e: dict, h: np.ndarray, lk: np.ndarray, hcols: list[str], lcols: list[str]
    ) -> None:
        for arr, cols in ((h.reshape(len(h), -1), hcols), (lk.reshape(len(lk), -1), lcols)):
            bad = ~np.isfinite(arr)
            if bad.any():
                r, col = np.argwhere(bad)[0]
                raise SessionFormatError(
                    f"{path}: repetition {e['repetition']}, frame {r}: column {cols[col]!r} is "
                    f"NaN/inf ({int(bad.sum())} values)"
                )
        for arr, cols, what in ((h[..., 3:], hcols, "hand"), (lk[..., 3:], lcols, "link")):
            norm = np.linalg.norm(arr.astype(np.float64), axis=-1)
            bad = np.abs(norm - 1.0) > self.quat_tolerance
            if bad.any():
                idx = np.argwhere(bad)[0]
                col = cols[int(np.ravel_multi_index(tuple(idx[1:]), bad.shape[1:])) * 7 + 3]
                raise SessionFormatError(
                    f"{path}: repetition {e['repetition']}, frame {idx[0]}: {what} quaternion "
                    f"{col.rsplit('_', 2)[0]}_rot_* has norm {norm[tuple(idx)]:.4f}, not 1"
                )


__all__ = ["SessionDataset", "SessionData", "SessionFormatError", "write_sessions", "participant_id", "POSE_SUFFIXES"]
