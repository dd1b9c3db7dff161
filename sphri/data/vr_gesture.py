"""``VRGestureData`` (``data=vr_gesture``): the reference study's recorded dataset.

Reads ``ROOT/{region}/participant_XX/participant_XX.parquet`` and its
manifest (layout in :mod:`sphri.data.format`), lazily: only the selected
regions' folders, participants' files, the hand's pose columns and the rows of
the selected trials (a pyarrow filter on ``trial_ordinal``) are read.

Validation. Errors (:class:`DatasetError`, naming file, trial and column):
missing or misnamed columns, an unknown gesture label, duplicated or missing
``frame_index_in_trial``, a manifest that disagrees with its parquet file
(row total, a trial's rows, frame count, label or id). Repairs (counted in
``GestureDataset.repairs`` and logged per file, never silent):

- ``held_invalid_pose``: a capsule pose with a NaN/inf position or a NaN,
  infinite or zero quaternion (tracking loss) takes the last valid pose of the
  same capsule in the same trial (the first valid one for leading frames);
- ``normalized_quaternion``: a quaternion whose norm is off 1 by more than
  ``quat_tolerance`` is scaled to unit norm;
- ``dropped_short_trial``: a trial with fewer than ``min_frames`` frames (the
  real data has three 1-frame trials) is dropped, by its manifest entry,
  before anything is read;
- ``dropped_untracked_trial``: a trial where some capsule is never valid is
  dropped (nothing to hold);
- ``frame_range_mismatch``: a trial whose ``frame`` column does not span the
  manifest's ``start_frame``..``end_frame`` (kept; the poses are unaffected).

A trial whose ``frame`` column goes backwards once its rows are put in
``frame_index_in_trial`` order (a reversed or shuffled index, which would
reorder the poses) is an error naming the file, trial and both columns.

Plausibility (:func:`check_position_scale`): positions are in ``data.units``
(m by default, scaled to metres on load); a participant whose hand is 100 or
1000 times its capsule model's size (positions in cm or mm) or far off the
robot is refused, naming the file and the likely unit; so is a single trial
whose scale disagrees (one trial in mm among trials in metres), by its
ordinal. A participant left
with no usable trial is named in a warning (``participant_without_trials``)
and the run's summary says how many participants its folds cover.

Duplicates (:mod:`sphri.data.duplicates`): two participant ids holding
near-identical trials (a copied participant folder) are refused by default,
naming both ids (``data.duplicates=warn`` loads them with a warning,
``off`` skips the check).
"""

from __future__ import annotations

import difflib
import logging
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from sphri.data.duplicates import DUPLICATE_POLICIES, describe, find_duplicates, fingerprint
from sphri.data.format import (
    GENERATOR_KEY,
    GENERATOR_VALUE,
    INTEGER_COLUMNS,
    META_COLUMNS,
    PARTICIPANT_RE,
    POSE_SUFFIXES,
    STRING_COLUMNS,
    ManifestError,
    make_trials_frame,
    manifest_path,
    parquet_path,
    pose_columns,
    read_manifest,
)
from sphri.data.repair import hold_last_valid
from sphri.data.schema import POSITION_UNITS
from sphri.types import GESTURES, GestureDataset, HandModel, Robot

log = logging.getLogger(__name__)

#: Frame rate assumed for recorded data without a ``frame_rate_hz`` manifest
#: key: the study's hand tracking ran at about 30 Hz, and its trial lengths
#: (median 96-157 frames rest to rest) only fit CoST's contact durations at
#: that rate (see :mod:`sphri.data.reference_stats`).
DEFAULT_FRAME_RATE_HZ = 30.0


class DatasetError(ValueError):
    """Recorded data is malformed; the message names the file, trial and column."""


#: A hand's median size (capsule centres' largest distance from their mean)
#: over its capsule model's size (:func:`hand_model_size_m`) must lie in this
#: range; in metres it is about 0.5 (0.069 / 0.13 m on the synthetic study),
#: in cm about 50 and in mm about 500.
HAND_SCALE_RANGE = (0.05, 5.0)
#: Hands whose median distance from the link frame's origin exceeds this many
#: robot sizes (and 2 m) are refused: they never come near the robot.
ROBOT_DISTANCE_LIMIT = 10.0


def hand_model_size_m(hand: HandModel) -> float:
    """A hand's size from its capsule model (m): longest capsule plus two radii."""
    return float(np.max(hand.height_m) + 2 * np.max(hand.radius_m))


def _likely_unit(ratio: float, units: str) -> str:
    return min(POSITION_UNITS, key=lambda u: abs(np.log10(ratio * POSITION_UNITS[u] / POSITION_UNITS[units] / 0.5)))


def check_position_scale(
    where: str,
    who: str,
    poses: Sequence[np.ndarray],
    hand: HandModel,
    robot: Robot | None,
    region: str,
    units: str,
    trials: Sequence[dict] | None = None,
) -> None:
    """Refuse positions whose scale cannot be metres (see the module docstring); ``poses`` (F, C, 7) in metres.

    The participant's scale is the median over its frames; each trial's own median (up to 20
    frames) must then be plausible too, so one trial in another unit is named by ``trials[i]``.
    """
    if not poses:
        return
    sub = [q[:: max(1, len(q) // 20), :, :3].astype(np.float64) for q in poses]
    spans = [np.linalg.norm(q - q.mean(axis=1, keepdims=True), axis=2).max(axis=1) for q in sub]
    p = np.concatenate(sub)
    centre = p.mean(axis=1)
    span = float(np.median(np.concatenate(spans)))
    size = hand_model_size_m(hand)
    ratio = span / size
    if not (HAND_SCALE_RANGE[0] <= ratio <= HAND_SCALE_RANGE[1]):
        guess = _likely_unit(ratio, units)
        likely = f"; they look like {guess}: set data.units={guess} or convert the file" if guess != units else ""
        raise DatasetError(
            f"{where}: {who}'s hand positions are implausible in data.units={units}: the hand spans "
            f"{span:.3g} m (median) while its capsule model is {size:.3g} m across{likely}"
        )
    with np.errstate(invalid="ignore"):
        per_trial = np.array([np.nanmedian(s) if s.size else np.nan for s in spans]) / size
    odd = np.flatnonzero(~((per_trial >= HAND_SCALE_RANGE[0]) & (per_trial <= HAND_SCALE_RANGE[1])))
    if odd.size:
        i = int(odd[0])
        t = trials[i] if trials is not None else {"trial_ordinal": i + 1, "trial_id": "?"}
        guess = _likely_unit(float(per_trial[i]), units) if np.isfinite(per_trial[i]) else "?"
        raise DatasetError(
            f"{where}: trial {t['trial_ordinal']} ({t['trial_id']}): the hand spans {per_trial[i] * size:.3g} m "
            f"(median) while {who}'s other trials span {span:.3g} m and its capsule model is {size:.3g} m across: "
            f"this trial looks like {guess}, the others like data.units={units} ({odd.size} trial(s) affected); "
            f"convert the trial"
        )
    if robot is not None and region in robot.regions:
        link = robot.link_for(region)
        reach = float(np.linalg.norm(np.asarray(link.vertices), axis=1).max())
        dist = float(np.median(np.linalg.norm(centre, axis=1)))
        limit = max(2.0, ROBOT_DISTANCE_LIMIT * reach)
        if dist > limit:
            raise DatasetError(
                f"{where}: {who}'s hand stays {dist:.3g} m (median) from link {link.name!r}, which reaches "
                f"{reach:.3g} m from its origin (limit {limit:.3g} m): wrong units (data.units={units}) or frame?"
            )


def column_problems(ppath: Path, schema: pa.Schema, hand: HandModel) -> list[str]:
    """Every column problem of a participant's parquet file (its arrow ``schema``), one line each: the
    missing columns (with the close names that may be misnamed ones), then each column of the wrong type
    (:mod:`sphri.data.recording_schema`: text, integer or float)."""
    have = list(schema.names)
    want = list(META_COLUMNS) + pose_columns(hand.names)
    missing = [c for c in want if c not in have]
    problems = []
    if missing:
        extra = [c for c in have if c not in want]
        hints = []
        for m in missing[:10]:
            close = difflib.get_close_matches(m, extra, n=1, cutoff=0.75)
            if close:
                hints.append(f"{close[0]!r} for {m!r}")
        hint = f"; misnamed? found {', '.join(hints)}" if hints else ""
        more = f" (and {len(missing) - 10} more)" if len(missing) > 10 else ""
        problems.append(f"{ppath}: missing column(s) {missing[:10]}{more}{hint}")
    for col in want:
        if col not in have:
            continue
        typ = schema.field(col).type
        numeric = pa.types.is_integer(typ) or pa.types.is_floating(typ)
        if col in STRING_COLUMNS:
            if not (pa.types.is_string(typ) or pa.types.is_large_string(typ) or pa.types.is_dictionary(typ)):
                problems.append(f"{ppath}: column {col} has type {typ}, expected strings")
        elif not numeric:
            problems.append(f"{ppath}: column {col} has type {typ}, expected numbers")
        elif col in INTEGER_COLUMNS and not pa.types.is_integer(typ):
            problems.append(f"{ppath}: column {col} has type {typ}, expected integers")
    return problems


@dataclass
class _Read:
    """What :meth:`VRGestureData.load` has read so far: repairs, trial records and their poses (F, C, 7) in
    metres, the next trial's first frame (``start``), whether each manifest was sphri-generated, the manifests'
    frame rates (Hz), usable trials per participant and the trials' fingerprints (for duplicates)."""

    repairs: Counter[str] = field(default_factory=Counter)
    records: list[dict] = field(default_factory=list)
    chunks: list[np.ndarray] = field(default_factory=list)
    generators: set[bool] = field(default_factory=set)
    rates: set[float] = field(default_factory=set)
    start: int = 0
    n_usable: Counter[str] = field(default_factory=Counter)
    prints: list = field(default_factory=list)


class _Notes:
    """Repairs of one file: counted in ``repairs`` and logged as one warning per kind."""

    SHOWN = 5

    def __init__(self, path: Path, repairs: Counter):
        self.path = path
        self.repairs = repairs
        self.items: dict[str, list[str]] = {}

    def add(self, kind: str, count: int, detail: str) -> None:
        self.repairs[kind] += count
        self.items.setdefault(kind, []).append(detail)

    def flush(self) -> None:
        for kind, details in self.items.items():
            more = f"; and {len(details) - self.SHOWN} more trial(s)" if len(details) > self.SHOWN else ""
            log.warning("%s: %s: %s%s", self.path, kind, "; ".join(details[: self.SHOWN]), more)
        self.items.clear()


def find_participants(root: Path, regions: Sequence[str]) -> list[str]:
    """Sorted participant ids found under any of ``root/{region}``.

    Raises :class:`DatasetError` naming the folder when ``root`` or a region
    folder does not exist (listing the regions that do).
    """
    root = Path(root)
    if not root.is_dir():
        raise DatasetError(f"data.root={str(root)!r}: no such directory")
    found: set[str] = set()
    for region in regions:
        rdir = root / region
        if not rdir.is_dir():
            have = sorted(p.name for p in root.iterdir() if p.is_dir() and p.name != "assets")
            raise DatasetError(f"{rdir}: no such region folder (data.regions={list(regions)}; found {have})")
        found.update(p.name for p in rdir.iterdir() if p.is_dir() and PARTICIPANT_RE.match(p.name))
    return sorted(found, key=_participant_order)


def _participant_order(name: str) -> tuple[int, str]:
    """Sort key of a participant folder name (one :data:`PARTICIPANT_RE` matches): its number, then the name."""
    return int(name.removeprefix("participant_")), name


class VRGestureData:
    """The recorded VR gesture dataset at ``root`` (see the module docstring).

    ``participants``: first N participants (sorted ids; None = all).
    ``repetitions``: at most this many trials per gesture per participant and
    region, first by ordinal (None = all). ``regions``/``gestures``: what to
    read. ``min_frames``: shorter trials are dropped. ``frame_rate_hz``: None
    takes the manifests' ``frame_rate_hz`` (sphri-written datasets) or
    :data:`DEFAULT_FRAME_RATE_HZ`. ``quat_tolerance``: allowed deviation of a
    quaternion norm from 1 before it is re-normalized. ``seed`` is unused
    (recorded data); it is accepted so every data component shares the keys.
    """

    VERSION = "1"
    #: Recorded poses do not depend on the robot config (its cache key omits it).
    USES_ROBOT = False

    def __init__(
        self,
        root: str | None = None,
        seed: int = 0,
        participants: int | None = None,
        repetitions: int | None = None,
        regions: Sequence[str] = ("arm",),
        gestures: Sequence[str] = GESTURES,
        min_frames: int = 10,
        frame_rate_hz: float | None = None,
        quat_tolerance: float = 1e-3,
        units: str = "m",
        duplicates: str = "refuse",
    ):
        if root is None:
            raise DatasetError(
                "data.root is not set: give the dataset folder, e.g. data.root=/path/to/VR-gesture-dataset"
            )
        self.root = Path(root)
        self.seed = int(seed)
        self.participants = participants
        self.repetitions = repetitions
        self.regions = list(regions)
        self.gestures = list(gestures)
        unknown = [g for g in self.gestures if g not in GESTURES]
        if unknown:
            raise DatasetError(f"data.gestures: unknown gesture(s) {unknown}; known: {list(GESTURES)}")
        self.min_frames = int(min_frames)
        self.frame_rate_hz = frame_rate_hz
        self.quat_tolerance = float(quat_tolerance)
        if units not in POSITION_UNITS:
            raise DatasetError(f"data.units={units!r} is invalid: allowed values: {list(POSITION_UNITS)}")
        self.units = units
        if duplicates not in DUPLICATE_POLICIES:
            raise DatasetError(f"data.duplicates={duplicates!r} is invalid: allowed values: {list(DUPLICATE_POLICIES)}")
        self.duplicates = duplicates

    # ------------------------------------------------------------------ public
    def load(self, hand: HandModel, robot: Robot | None = None) -> GestureDataset:
        """Read the selected trials into a :class:`GestureDataset` (poses float32, link frames)."""
        pids = self._participant_ids(robot)
        read = _Read()
        for pid in pids:
            for region in self.regions:
                if not (self.root / region / pid).is_dir():
                    log.info("%s has no %s folder; skipped", pid, region)
                    continue
                self._read_participant(pid, region, hand, robot, read)
        self._note_empty(pids, read)
        self._check_duplicates(read)
        if len(read.generators) > 1:
            raise DatasetError(f"{self.root}: mixes sphri-generated and recorded manifests ('{GENERATOR_KEY}' key)")
        synthetic = read.generators == {True}
        if len(read.rates) > 1:
            raise DatasetError(f"{self.root}: manifests disagree on frame_rate_hz: {sorted(read.rates)}")
        rate = self._frame_rate(read.rates)
        poses = np.concatenate(read.chunks, axis=0) if read.chunks else np.zeros((0, hand.n_capsules, 7), np.float32)
        if read.repairs:
            log.warning("%s: repairs applied on load: %s", self.root, dict(read.repairs))
        return GestureDataset(
            name="synthetic" if synthetic else "vr_gesture",
            synthetic=synthetic,
            hand=hand,
            trials=make_trials_frame(read.records),
            poses=np.ascontiguousarray(poses, dtype=np.float32),
            frame_rate_hz=rate,
            repairs=dict(read.repairs),
        )

    # --------------------------------------------------------------- internals
    def _participant_ids(self, robot: Robot | None) -> list[str]:
        """The participant ids to read (the first ``participants`` found), after checking the robot has the regions."""
        if robot is not None:
            for region in self.regions:
                robot.link_for(region)  # UnknownRegion naming the robot's regions
        pids = find_participants(self.root, self.regions)
        if not pids:
            raise DatasetError(f"{self.root}: no participant_XX folders under {self.regions}")
        if self.participants is not None:
            pids = pids[: self.participants]
        return pids

    def _read_participant(self, pid: str, region: str, hand: HandModel, robot: Robot | None, read: _Read) -> None:
        """Read one participant's trials in ``region`` (positions checked for scale) and add them to ``read``."""
        manifest, trials, poses = self.load_participant(pid, region, hand, read.repairs)
        check_position_scale(
            str(parquet_path(self.root, region, pid)), pid, poses, hand, robot, region, self.units, trials
        )
        read.n_usable[pid] += len(trials)
        read.generators.add(manifest.get(GENERATOR_KEY) == GENERATOR_VALUE)
        if "frame_rate_hz" in manifest:
            read.rates.add(float(manifest["frame_rate_hz"]))
        for t, p in zip(trials, poses):
            read.records.append(
                dict(
                    participant=pid,
                    region=region,
                    trial_ordinal=t["trial_ordinal"],
                    trial_id=t["trial_id"],
                    gesture=t["gesture_label"],
                    start=read.start,
                    n_frames=len(p),
                )
            )
            read.chunks.append(p)
            read.start += len(p)
            if self.duplicates != "off":
                read.prints.append((pid, (region, t["gesture_label"], len(p)), fingerprint(p)))

    def _note_empty(self, pids: list[str], read: _Read) -> None:
        """Count and warn about the participants (with a folder) left without a usable trial."""
        empty = [
            pid for pid in pids if read.n_usable[pid] == 0 and any((self.root / r / pid).is_dir() for r in self.regions)
        ]
        if empty:
            read.repairs["participant_without_trials"] += len(empty)
            log.warning(
                "%s: participant(s) %s have no usable trial (gestures %s, min_frames %d): left out of the dataset",
                self.root,
                empty,
                self.gestures,
                self.min_frames,
            )

    def _check_duplicates(self, read: _Read) -> None:
        """Refuse (or, under ``duplicates=warn``, count and warn about) participants holding near-identical trials."""
        for pair in find_duplicates(read.prints):
            if self.duplicates == "refuse":
                raise DatasetError(
                    f"{self.root}: {describe(pair)}: a copied participant folder? Remove one, or set "
                    "data.duplicates=warn to load both"
                )
            read.repairs["duplicate_participants"] += 1
            log.warning(
                "%s: duplicate_participants: %s: both loaded (data.duplicates=warn); they are not independent "
                "people, so leave-one-subject-out overstates accuracy",
                self.root,
                describe(pair),
            )

    def _frame_rate(self, rates: set[float]) -> float:
        if self.frame_rate_hz is not None:
            if rates and float(self.frame_rate_hz) not in rates:
                log.warning(
                    "data.frame_rate_hz=%s overrides the manifests' frame_rate_hz=%s", self.frame_rate_hz, rates
                )
            return float(self.frame_rate_hz)
        return rates.pop() if rates else DEFAULT_FRAME_RATE_HZ

    def _select(self, mpath: Path, manifest: dict, notes: _Notes) -> list[dict]:
        """Manifest trials to read: selected gestures, long enough, capped per gesture."""
        per_gesture: Counter[str] = Counter()
        out = []
        for t in sorted(manifest["trials"], key=lambda t: t["trial_ordinal"]):
            g = t["gesture_label"]
            if g not in GESTURES:
                raise DatasetError(
                    f"{mpath}: trial {t['trial_ordinal']}: column gesture_label={g!r} is not a known gesture "
                    f"({list(GESTURES)})"
                )
            if g not in self.gestures:
                continue
            if t["frame_count"] < self.min_frames:
                notes.add(
                    "dropped_short_trial",
                    1,
                    f"trial {t['trial_ordinal']} ({t['trial_id']}) has "
                    f"{t['frame_count']} frame(s) < data.min_frames={self.min_frames}, dropped",
                )
                continue
            if self.repetitions is not None and per_gesture[g] >= self.repetitions:
                continue
            per_gesture[g] += 1
            out.append(t)
        return out

    def load_participant(
        self, pid: str, region: str, hand: HandModel, repairs: Counter
    ) -> tuple[dict, list[dict], list[np.ndarray]]:
        """One participant's manifest, selected trials and their poses (metres), every file checked; repairs are
        counted in ``repairs``."""
        mpath = manifest_path(self.root, region, pid)
        ppath = parquet_path(self.root, region, pid)
        manifest = read_manifest(mpath)
        if manifest["participant_id"] != pid or manifest["body_region"] != region:
            raise ManifestError(
                f"{mpath}: participant_id={manifest['participant_id']!r}, body_region={manifest['body_region']!r} "
                f"disagree with its folder ({region}/{pid})"
            )
        notes = _Notes(mpath, repairs)
        wanted = self._select(mpath, manifest, notes)
        notes.flush()
        if not ppath.is_file():
            raise FileNotFoundError(f"pose file missing: {ppath} (its manifest {mpath.name} is there)")
        try:
            with pq.ParquetFile(ppath) as pf:
                schema, n_rows = pf.schema_arrow, pf.metadata.num_rows
        except (pa.ArrowException, OSError) as exc:
            raise DatasetError(f"{ppath}: not a readable parquet file ({exc})") from None
        problems = column_problems(ppath, schema, hand)
        if problems:
            raise DatasetError(problems[0])
        if n_rows != manifest["num_frames_total"]:
            raise ManifestError(
                f"{mpath}: num_frames_total={manifest['num_frames_total']} but {ppath.name} has {n_rows} rows"
            )
        if not wanted:
            return manifest, [], []
        ordinals = [int(t["trial_ordinal"]) for t in wanted]
        columns = list(META_COLUMNS) + pose_columns(hand.names)
        try:
            table = pq.read_table(
                ppath, columns=columns, filters=[("trial_ordinal", "in", ordinals)], page_checksum_verification=True
            )
        except (pa.ArrowException, OSError) as exc:  # e.g. a damaged data page: "ZSTD decompression failed"
            raise DatasetError(f"{ppath}: cannot read its pose data ({type(exc).__name__}: {exc})") from None
        notes = _Notes(ppath, repairs)
        try:
            return manifest, *self._trials_from_table(ppath, table, wanted, hand, notes)
        finally:
            notes.flush()

    def _trials_from_table(
        self, ppath: Path, table: pa.Table, wanted: list[dict], hand: HandModel, notes: _Notes
    ) -> tuple[list[dict], list[np.ndarray]]:
        """The ``wanted`` manifest trials that survive repair and their poses (F, C, 7) in metres, read from
        ``table`` (the rows of ``ppath`` selected for them); every row and trial checked against the manifest."""
        rows = self._sorted_rows(table, hand)
        _check_frame_index(ppath, rows)
        _check_frame_order(ppath, rows)
        out_trials: list[dict] = []
        out_poses: list[np.ndarray] = []
        for t in wanted:
            o, s, n = _check_trial(ppath, rows, t, notes)
            p, ok = self._repair(o, rows.poses[s : s + n], hand, notes)
            if ok:
                out_trials.append(t)
                out_poses.append(p)
        return out_trials, out_poses

    def _sorted_rows(self, table: pa.Table, hand: HandModel) -> _Rows:
        """The rows of ``table`` in (trial_ordinal, frame_index_in_trial) order, poses scaled to metres."""
        c = hand.n_capsules
        ordinal = table.column("trial_ordinal").to_numpy().astype(np.int64)
        fidx = table.column("frame_index_in_trial").to_numpy().astype(np.int64)
        frame = table.column("frame").to_numpy().astype(np.int64)
        order = np.lexsort((fidx, ordinal))
        ordinal, fidx, frame = ordinal[order], fidx[order], frame[order]
        labels = np.asarray(table.column("gesture_label").to_pylist(), dtype=object)[order]
        tids = np.asarray(table.column("trial_id").to_pylist(), dtype=object)[order]
        cols = pose_columns(hand.names)
        flat = np.empty((len(order), len(cols)), dtype=np.float32)
        for j, col in enumerate(cols):
            flat[:, j] = table.column(col).to_numpy(zero_copy_only=False).astype(np.float32, copy=False)
        poses = flat[order].reshape(len(order), c, len(POSE_SUFFIXES))
        if self.units != "m":
            poses[..., :3] *= np.float32(POSITION_UNITS[self.units])

        uniq, first, counts = np.unique(ordinal, return_index=True, return_counts=True)
        where = {int(o): (int(s), int(n)) for o, s, n in zip(uniq, first, counts)}
        return _Rows(ordinal, fidx, frame, labels, tids, poses, first, counts, where)

    def _repair(self, o: int, p: np.ndarray, hand: HandModel, notes: _Notes) -> tuple[np.ndarray, bool]:
        """Hold invalid capsule poses, normalize off-unit quaternions; False when unrepairable."""
        q64 = p[..., 3:].astype(np.float64)
        finite = np.isfinite(p).all(axis=-1)
        with np.errstate(invalid="ignore", over="ignore"):
            norm = np.sqrt((q64 * q64).sum(axis=-1))
        bad = ~finite | ~(norm >= 1e-8)
        if bad.any():
            fixed, orphan = hold_last_valid(p, bad, np.array([0]))
            if orphan.any():
                caps = [hand.names[i] for i in np.flatnonzero(orphan.any(axis=0))]
                notes.add(
                    "dropped_untracked_trial",
                    1,
                    f"trial {o}: capsule(s) {caps} never have a valid pose "
                    f"(columns {caps[0]}_pos_*/rot_*), trial dropped",
                )
                return p, False
            nb = int(bad.sum())
            caps = sorted({hand.names[i] for i in np.nonzero(bad)[1]})
            notes.add(
                "held_invalid_pose",
                nb,
                f"trial {o}: {nb} capsule pose(s) with NaN/inf/zero values "
                f"(capsules {caps}) held from the last valid frame",
            )
            p = fixed
            q64 = p[..., 3:].astype(np.float64)
            norm = np.sqrt((q64 * q64).sum(axis=-1))
        off = np.abs(norm - 1.0) > self.quat_tolerance
        if off.any():
            p = p.copy()
            p[..., 3:][off] = (q64[off] / norm[off][:, None]).astype(np.float32)
            caps = sorted({hand.names[i] for i in np.nonzero(off)[1]})
            notes.add(
                "normalized_quaternion",
                int(off.sum()),
                f"trial {o}: {int(off.sum())} quaternion(s) with |q| "
                f"off 1 by > {self.quat_tolerance:g} (capsules {caps}, columns *_rot_*) normalized",
            )
        return p, True


@dataclass
class _Rows:
    """A participant file's selected rows in (trial_ordinal, frame_index_in_trial) order: those columns, the
    ``frame`` column, labels and trial ids, poses (R, C, 7) float32 in metres, and where each trial starts
    (``first``), how many rows it has (``counts``) and both by ordinal (``where``: ordinal -> (start, rows))."""

    ordinal: np.ndarray
    fidx: np.ndarray
    frame: np.ndarray
    labels: np.ndarray
    tids: np.ndarray
    poses: np.ndarray
    first: np.ndarray
    counts: np.ndarray
    where: dict[int, tuple[int, int]]


def _check_frame_index(ppath: Path, rows: _Rows) -> None:
    """Refuse (:class:`DatasetError`) a trial whose frame_index_in_trial is not 0..n-1."""
    ordinal, fidx, first, counts = rows.ordinal, rows.fidx, rows.first, rows.counts
    pos_in_trial = np.arange(len(ordinal)) - np.repeat(first, counts)
    broken = np.unique(ordinal[fidx != pos_in_trial])
    if broken.size:
        o = int(broken[0])
        s, n = rows.where[o]
        idx = fidx[s : s + n]
        dup = np.unique(idx[np.r_[False, np.diff(idx) == 0]])
        missing = np.setdiff1d(np.arange(idx.max() + 1 if n else 0), idx)
        what = []
        if dup.size:
            what.append(f"duplicated values {dup[:10].tolist()}")
        if missing.size:
            what.append(f"missing values {missing[:10].tolist()}")
        if idx.min() < 0:
            what.append("negative values")
        raise DatasetError(
            f"{ppath}: trial {o}: column frame_index_in_trial has {'; '.join(what)} "
            f"(expected 0..{n - 1}; {broken.size} trial(s) affected)"
        )


def _check_frame_order(ppath: Path, rows: _Rows) -> None:
    """Refuse (:class:`DatasetError`) a trial whose ``frame`` column goes backwards in frame_index_in_trial order:
    a reversed or shuffled index would silently reorder the poses."""
    ordinal, fidx, frame = rows.ordinal, rows.fidx, rows.frame
    back = np.flatnonzero((np.diff(frame) < 0) & (ordinal[1:] == ordinal[:-1])) + 1
    if back.size:
        r = int(back[0])
        o = int(ordinal[r])
        raise DatasetError(
            f"{ppath}: trial {o}: column frame goes backwards ({int(frame[r - 1])} -> {int(frame[r])}) at "
            f"frame_index_in_trial={int(fidx[r])}: the index disagrees with the recording order "
            f"({np.unique(ordinal[back]).size} trial(s) affected)"
        )


def _check_trial(ppath: Path, rows: _Rows, t: dict, notes: _Notes) -> tuple[int, int, int]:
    """(ordinal, first row, rows) of the manifest trial ``t`` in ``rows``, after checking its row count, label
    and id against the manifest (errors) and its frame range (noted in ``notes``)."""
    where, labels, tids, frame = rows.where, rows.labels, rows.tids, rows.frame
    o = int(t["trial_ordinal"])
    if o not in where:
        raise ManifestError(f"{ppath}: trial {o} ({t['trial_id']}) is in the manifest but has no rows")
    s, n = where[o]
    if n != t["frame_count"]:
        raise ManifestError(f"{ppath}: trial {o}: {n} rows but the manifest's frame_count is {t['frame_count']}")
    lab = set(labels[s : s + n].tolist())
    if len(lab) != 1:
        raise DatasetError(f"{ppath}: trial {o}: column gesture_label has several values {sorted(map(str, lab))}")
    g = lab.pop()
    if g not in GESTURES:
        raise DatasetError(f"{ppath}: trial {o}: column gesture_label={g!r} is not a known gesture ({list(GESTURES)})")
    if g != t["gesture_label"]:
        raise ManifestError(f"{ppath}: trial {o}: gesture_label {g!r} but the manifest says {t['gesture_label']!r}")
    ids = set(tids[s : s + n].tolist())
    if ids != {t["trial_id"]}:
        raise ManifestError(
            f"{ppath}: trial {o}: column trial_id {sorted(map(str, ids))} but the manifest says {t['trial_id']!r}"
        )
    if "start_frame" in t and "end_frame" in t and n:
        if frame[s] != t["start_frame"] or frame[s + n - 1] != t["end_frame"]:
            notes.add(
                "frame_range_mismatch",
                1,
                f"trial {o}: column frame spans {frame[s]}..{frame[s + n - 1]}, "
                f"the manifest says {t['start_frame']}..{t['end_frame']} (kept)",
            )
    return o, s, n
