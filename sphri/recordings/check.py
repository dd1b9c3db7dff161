"""``sphri check-data DIR``: a recording folder against the recording format, every problem one line.

The folder's kind comes from what it holds: ``sessions.json`` is whole-body sessions, else
``{region}/participant_XX/participant_XX_manifest.json`` files are gesture trials. Each file is
checked by the loaders' own validation (:mod:`sphri.data.format`, :mod:`sphri.data.vr_gesture`,
:mod:`sphri.sessions.format`), one participant at a time, so a problem in one file does not hide
those of the others; a file's parquet columns are all checked before its rows. What the loader
would repair on load (a NaN pose held, a quaternion normalized, a short trial dropped) is counted
in the summary, not a problem; two participants holding near-identical recordings (a copied folder),
which the loaders refuse, are one.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from sphri.data.duplicates import describe, find_duplicates, fingerprint
from sphri.data.format import GENERATOR_KEY, PARTICIPANT_RE, ManifestError, manifest_path, parquet_path
from sphri.data.vr_gesture import DatasetError, VRGestureData, check_position_scale, column_problems
from sphri.hand.capsules import HandCapsules, HandDefinitionError
from sphri.recordings.capsules import documented_hand
from sphri.sessions.format import SessionData, SessionFormatError, read_header
from sphri.types import GESTURES

#: Errors a loader raises on a malformed file (each names the file and field).
FILE_ERRORS = (DatasetError, ManifestError, SessionFormatError, HandDefinitionError, OSError, ValueError)


@dataclass
class Check:
    """What :func:`check_folder` found: the folder's kind, its problems (one line each) and a summary."""

    kind: str
    problems: list[str] = field(default_factory=list)
    summary: str = ""


def _gesture_folders(root: Path) -> list[tuple[str, str]]:
    return sorted(
        (r.name, p.name)
        for r in root.iterdir()
        if r.is_dir() and r.name != "assets"
        for p in r.iterdir()
        if p.is_dir() and PARTICIPANT_RE.match(p.name)
    )


def _duplicates(root: Path, prints: list, what: str) -> list[str]:
    """A line for each two participants holding near-identical recordings, which the loaders refuse."""
    return [
        f"{root}: {describe(pair, what)}: a copied participant folder? (the loader refuses it; data.duplicates=warn "
        "loads both)"
        for pair in find_duplicates(prints)
    ]


def check_gestures(root: Path) -> Check:
    out = Check("gesture trials")
    definition = root / "assets" / "hand_capsule_definition.json"
    try:
        hand = HandCapsules(definition_path=str(definition)).build() if definition.is_file() else documented_hand()
    except FILE_ERRORS as exc:
        out.problems.append(str(exc))
        return out
    repairs: Counter[str] = Counter()
    trials = frames = 0
    rates, generators, versions = set(), set(), set()
    prints: list = []
    folders = _gesture_folders(root)
    for region, pid in folders:
        mpath, ppath = manifest_path(root, region, pid), parquet_path(root, region, pid)
        loader = VRGestureData(root=str(root), regions=[region], gestures=GESTURES, min_frames=1)
        try:
            if ppath.is_file():
                import pyarrow.parquet as pq

                cols = column_problems(ppath, pq.read_schema(ppath), hand)
                if cols:
                    out.problems += cols
                    continue
            manifest, ts, poses = loader.load_participant(pid, region, hand, repairs)
            check_position_scale(str(ppath), pid, poses, hand, None, region, "m", ts)
        except FILE_ERRORS as exc:
            out.problems.append(" ".join(str(exc).split()) or f"{mpath}: {type(exc).__name__}")
            continue
        trials += len(ts)
        frames += sum(len(p) for p in poses)
        prints += [(pid, (region, t["gesture_label"], len(p)), fingerprint(p)) for t, p in zip(ts, poses)]
        rates.add(float(manifest.get("frame_rate_hz", 30.0)))
        generators.add(manifest.get(GENERATOR_KEY))
        versions.add(int(manifest.get("format_version", 1)))
    if len(rates) > 1:
        out.problems.append(f"{root}: manifests disagree on frame_rate_hz: {sorted(rates)}; one rate per dataset")
    if len(generators) > 1:
        out.problems.append(f"{root}: mixes sphri-generated and recorded manifests ('{GENERATOR_KEY}' key)")
    out.problems += _duplicates(root, prints, "trials")
    regions = sorted({r for r, _ in folders})
    fixes = f"; the loader would repair: {dict(repairs)}" if repairs else ""
    out.summary = (
        f"{root}: gesture trials, format version(s) {sorted(versions)}: {len(regions)} region(s) {regions}, "
        f"{len({p for _, p in folders})} participant(s), {trials} trials, {frames} frames at "
        f"{', '.join(f'{r:g}' for r in sorted(rates))} Hz, {hand.n_capsules} capsules{fixes}"
    )
    return out


def check_sessions(root: Path) -> Check:
    out = Check("sessions")
    try:
        header = read_header(root)
    except FILE_ERRORS as exc:
        out.problems.append(str(exc))
        return out
    loader = SessionData(root=str(root))
    pids = sorted(p.name for p in root.iterdir() if p.is_dir() and (p / "manifest.json").is_file())
    if not pids:
        out.problems.append(f"{root}: no participant folder with a manifest.json")
    sessions = frames = 0
    rates: set[float] = set()
    prints: list = []
    for pid in pids:
        try:
            part = loader.load_participant(root, pid, header["hand_model"], list(header["links"]))
        except FILE_ERRORS as exc:
            out.problems.append(" ".join(str(exc).split()))
            continue
        sessions += len(part.records)
        frames += sum(r["n_frames"] for r in part.records)
        rates |= part.rates
        prints += part.prints
    if len(rates) > 1:
        out.problems.append(f"{root}: manifests mix frame rates {sorted(rates)}; one rate per dataset")
    out.problems += _duplicates(root, prints, "sessions")
    out.summary = (
        f"{root}: sessions, {header['format']} version {header['version']}: {len(pids)} participant(s), "
        f"{sessions} sessions, {frames} frames at {', '.join(f'{r:g}' for r in sorted(rates))} Hz, "
        f"{len(header['links'])} link(s), hands {list(header['hands'])}"
    )
    return out


def check_folder(root: str | Path) -> Check:
    """Check the recording folder ``root`` (see the module docstring)."""
    root = Path(root)
    if not root.is_dir():
        return Check("none", [f"{root}: no such folder"])
    if (root / "sessions.json").is_file():
        return check_sessions(root)
    if _gesture_folders(root):
        return check_gestures(root)
    return Check(
        "none",
        [
            f"{root}: neither sessions.json (sessions) nor {{region}}/participant_XX/ folders (gesture trials): "
            "not a recording folder (docs/RECORDING_FORMAT.md)"
        ],
    )
