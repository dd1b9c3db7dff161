"""The files a component reads, and their content fingerprints.

A schema declares each config field that names a file or folder the
component reads with :func:`input_path` (field metadata), once, next to the
field::

    density_path: str = input_path("")                              # one file
    root: Optional[str] = input_path(None, kind="dir")              # every file below
    links: Any = input_path(None, kind="map", relative_to="root")   # name -> file
    path: str = input_path(MISSING, references="sphri.robots.urdf:mesh_files")

:func:`input_fingerprints` finds these fields in a composed config (through
each group's structured-config type) and fingerprints every file: a blake2b
hash of its bytes, rehashed only when its size, modification time, inode or
change time differ from the :class:`FingerprintMemo` (a small JSON file in the
cache folder, signed with the cache key ``SPHRI_CACHE_KEY`` when there is one).
The pipeline puts the fingerprints into the stage keys (:mod:`sphri.pipeline`)
and the config hash, so a file replaced at the same path recomputes the stages
that read it and everything below.
"""

from __future__ import annotations

import dataclasses
import hashlib
import hmac
import importlib
import json
import logging
import os
import stat
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf

from sphri.fsutil import write_atomic

log = logging.getLogger(__name__)

INPUT_META = "sphri_input"
KINDS = ("file", "dir", "map")
MEMO_NAME = "fingerprints.json"


def input_path(
    default: Any = None, *, kind: str = "file", relative_to: str | None = None, references: str | None = None
) -> Any:
    """A schema field naming what the component reads (see the module docstring).

    ``kind``: ``file`` (a path), ``dir`` (a folder: every file below it, hidden
    ones excepted) or ``map`` (a mapping name -> file path). ``relative_to``:
    the sibling field holding the folder relative paths start from.
    ``references``: ``"module:function"`` returning the further files a file
    names (e.g. a URDF's meshes).
    """
    if kind not in KINDS:
        raise ValueError(f"input_path kind must be one of {KINDS}, got {kind!r}")
    meta = {INPUT_META: {"kind": kind, "relative_to": relative_to, "references": references}}
    return dataclasses.field(default=default, metadata=meta)


_MEMO_PURPOSE = b"sphri fingerprint memo\n"


def _memo_digest(key: bytes, entries: bytes) -> str:
    """HMAC-SHA256 (hex) of a memo's entries with the cache key."""
    return hmac.new(key, _MEMO_PURPOSE + entries, hashlib.sha256).hexdigest()


class FingerprintMemo:
    """Content hashes of files, remembered by (size, mtime, inode, ctime); persisted at ``path`` if given.

    ``key``: the cache key (bytes, :attr:`sphri.cache.StageCache.key`) or None. With a key the file is
    ``{"entries": ..., "hmac": ...}`` and read only when the HMAC verifies: whoever can write to the cache
    folder cannot make a replaced file keep its old digest."""

    def __init__(self, path: str | os.PathLike | None = None, key: bytes | None = None):
        self.path = Path(path) if path is not None else None
        self.key = key
        self.entries: dict[str, list] = self._load()
        self.dirty = False
        self.hashed: list[str] = []

    def _load(self) -> dict[str, list]:
        if self.path is None:
            return {}
        try:
            data = json.loads(self.path.read_text())
        except (OSError, ValueError, RecursionError):  # unreadable or crafted: hashed again
            return {}
        if not isinstance(data, dict):
            return {}
        signed = isinstance(data.get("entries"), dict) and isinstance(data.get("hmac"), str)
        if self.key is None:
            entries = data["entries"] if signed else data
            return entries if isinstance(entries, dict) else {}
        body = json.dumps(data.get("entries"), sort_keys=True).encode() if signed else b""
        if not (signed and hmac.compare_digest(str(data["hmac"]), _memo_digest(self.key, body))):
            log.warning("fingerprint memo %s is not signed with the cache key; ignored (files hashed again)", self.path)
            return {}
        return data["entries"]

    def digest(self, path: Path) -> str:
        """``blake2b:<hex>`` of the file's bytes, ``missing`` when it does not exist."""
        key = str(path)
        try:
            st = path.stat()
        except (FileNotFoundError, NotADirectoryError):
            return "missing"
        except OSError as exc:
            return f"unreadable:{exc.errno}"
        kind = special_kind(st.st_mode)
        if kind is not None:  # never opened: a FIFO or a device would block or never end
            _warn_skipped([_describe_special(path) or f"{path} is {kind}"])
            return f"special:{kind}"
        sig = [st.st_size, st.st_mtime_ns, st.st_ino, st.st_ctime_ns]
        old = self.entries.get(key)
        if isinstance(old, list) and len(old) == 5 and old[:4] == sig:
            return old[4]
        try:
            with open(path, "rb") as fh:
                digest = "blake2b:" + hashlib.file_digest(fh, lambda: hashlib.blake2b(digest_size=16)).hexdigest()
        except OSError as exc:
            return f"unreadable:{exc.errno}"
        self.entries[key] = [*sig, digest]
        self.dirty = True
        self.hashed.append(key)
        return digest

    def save(self) -> None:
        """Write the memo (merged with what other processes wrote; best effort)."""
        if self.path is None or not self.dirty:
            return
        try:
            merged = {**self._load(), **self.entries}
            doc: Any = merged
            if self.key is not None:
                body = json.dumps(merged, sort_keys=True).encode()
                doc = {"entries": merged, "hmac": _memo_digest(self.key, body)}
            write_atomic(self.path, json.dumps(doc).encode())  # the umask's mode, as the cache entries
            self.dirty = False
        except OSError as exc:  # a read-only cache folder: fingerprints are recomputed next time
            log.debug("cannot write the fingerprint memo %s: %s", self.path, exc)


def special_kind(mode: int) -> str | None:
    """What a file of mode ``mode`` is when it is not a regular file or a folder (a FIFO, a device, a
    socket: reading one may block forever or never end), else None."""
    for test, name in (
        (stat.S_ISFIFO, "a FIFO (named pipe)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return name
    return None


def _describe_special(path: Path) -> str | None:
    """``'<path> is a FIFO (named pipe)'`` (or ``is a link to ...``) for a path that is not a regular
    file or folder; None otherwise (a missing or unreadable path included: the reader names those)."""
    try:
        kind = special_kind(path.stat().st_mode)
    except OSError:
        return None
    if kind is None:
        return None
    if path.is_symlink():
        return f"{path} is a link to {kind} ({os.path.realpath(path)})"
    return f"{path} is {kind}"


def _warn_skipped(skipped: list[str]) -> None:
    if skipped:
        log.warning(
            "skipped %d input file(s) that are not regular files (reading them could block forever): %s",
            len(skipped),
            "; ".join(skipped),
        )


def _files_below(root: Path, exclude: frozenset[Path] = frozenset()) -> list[Path]:
    """Regular files below ``root`` (sorted; hidden names and the ``exclude`` folders skipped).

    FIFOs, devices and sockets, and links to them, are skipped with a warning naming them."""
    out = []
    skipped: list[str] = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(
            d for d in dirnames if not d.startswith(".") and Path(dirpath, d).absolute() not in exclude
        )
        for f in sorted(filenames):
            if f.startswith("."):
                continue
            p = Path(dirpath) / f
            special = _describe_special(p)
            if special is None:
                out.append(p)
            else:
                skipped.append(special)
    _warn_skipped(skipped)
    return out


def _function(spec: str) -> Callable[..., Any]:
    """The function ``"module:name"`` names (a schema's ``references`` or ``INPUT_CHECK``)."""
    module, _, name = spec.partition(":")
    return getattr(importlib.import_module(module), name)


def _inputs_of(node: Any, resolve: bool) -> tuple[list[tuple[str, dict]], dict]:
    """``([(field, its input_path metadata)], the node's values)`` of the inputs the schema of ``node`` declares
    (none for a node without a schema, and then no values)."""
    schema = OmegaConf.get_type(node) if isinstance(node, DictConfig) else None
    if schema is None or not dataclasses.is_dataclass(schema):
        return [], {}
    specs = [(f.name, f.metadata[INPUT_META]) for f in dataclasses.fields(schema) if INPUT_META in f.metadata]
    values = OmegaConf.to_container(node, resolve=resolve) if specs else {}
    assert isinstance(values, dict)  # a DictConfig's container
    return specs, values


def declared_files(node: Any, exclude: frozenset[Path] = frozenset()) -> list[tuple[str, Path]]:
    """``(field, path)`` of every file the component configured by ``node`` reads (folders expanded).

    ``exclude``: folders never descended into (sphri's own output and cache
    folders, should a dataset folder hold them)."""
    specs, values = _inputs_of(node, resolve=True)
    out: list[tuple[str, Path]] = []
    for name, spec in specs:
        value = values.get(name)
        if value in (None, "", "???"):
            continue
        base = None
        if spec["relative_to"]:
            b = values.get(spec["relative_to"])
            base = Path(str(b)).expanduser() if b not in (None, "") else None
        if spec["kind"] != "map" and isinstance(value, (Mapping, list)):
            continue  # given inline (e.g. robot.parts as a mapping), not a file
        raw = list(value.values()) if spec["kind"] == "map" and isinstance(value, Mapping) else [value]
        for item in raw:
            if item in (None, ""):
                continue
            p = Path(str(item)).expanduser()
            if base is not None and not p.is_absolute():
                p = base / p
            p = p.absolute()
            if spec["kind"] == "dir" and p.is_dir():
                out += [(name, q) for q in _files_below(p, exclude)]
                continue
            out.append((name, p))
            if spec["references"] and p.is_file():
                try:
                    refs = list(_function(spec["references"])(p))
                except Exception as exc:  # the component reports an unreadable file itself
                    log.debug("cannot list the files %s names: %s", p, exc)
                    refs = []
                out += [(name, Path(r).absolute()) for r in refs]
    return out


def check_contents(node: Any) -> None:
    """Run the content check of the component configured by ``node``: its schema's ``INPUT_CHECK``
    (``"module:function"``, called with the node's resolved settings as a dict; e.g. a URDF robot's link
    names against the file), which raises an error naming the key. Nothing when the schema has none."""
    if not isinstance(node, DictConfig):
        return
    spec = getattr(OmegaConf.get_type(node), "INPUT_CHECK", "")
    if spec:
        _function(spec)(OmegaConf.to_container(node, resolve=True))


def missing_inputs(node: Any) -> list[tuple[str, Path, str]]:
    """``(field, path, expected)`` for each declared input of ``node`` that is not there: a ``file``
    field that names no file, a ``dir`` field that names no folder, a ``map`` entry that names no file
    (relative entries from their ``relative_to`` folder). Files a file refers to (a URDF's meshes) are
    the component's to check: some have fallbacks."""
    specs, values = _inputs_of(node, resolve=False)
    out = []
    for name, spec in specs:
        value = values.get(name)
        if value in (None, "", "???") or (isinstance(value, str) and "${" in value):
            continue
        base = values.get(spec["relative_to"]) if spec["relative_to"] else None
        base = Path(str(base)).expanduser() if isinstance(base, str) and base and "${" not in base else None
        if spec["kind"] == "map":
            items = [(f"{name}.{k}", v) for k, v in value.items()] if isinstance(value, Mapping) else []
        else:
            items = [(name, value)]
        for field, item in items:
            if not isinstance(item, (str, os.PathLike)) or item in ("",):
                continue
            p = Path(str(item)).expanduser()
            if base is not None and not p.is_absolute():
                p = base / p
            ok = p.is_dir() if spec["kind"] == "dir" else p.is_file()
            if not ok:
                out.append((field, p, "folder" if spec["kind"] == "dir" else "file"))
    return out


def fingerprints(node: Any, memo: FingerprintMemo, exclude: frozenset[Path] = frozenset()) -> dict[str, str]:
    """``{absolute path: digest}`` of the files the component configured by ``node`` reads."""
    return {str(p): memo.digest(p) for _, p in declared_files(node, exclude)}


_MEMOS: dict[tuple[str, bytes | None], FingerprintMemo] = {}


def memo_at(cache_dir: str | os.PathLike | None, key: bytes | None) -> FingerprintMemo:
    """The fingerprint memo kept in ``cache_dir`` (None: in memory only), one per process and ``key``
    (the cache's HMAC key, or None)."""
    if cache_dir is None:
        return FingerprintMemo(None)
    path = str(Path(cache_dir).absolute() / MEMO_NAME)
    memo = _MEMOS.get((path, key))
    if memo is None:
        memo = _MEMOS[(path, key)] = FingerprintMemo(path, key)
    return memo


def memo_for(cfg: DictConfig, key: bytes | None) -> FingerprintMemo:
    """The fingerprint memo of ``cfg``'s cache folder (in memory only when the cache is disabled)."""
    cache = cfg.get("cache")
    enabled = cache is not None and bool(cache.get("enabled", True))
    return memo_at(str(cache.dir) if enabled else None, key)


def input_fingerprints(cfg: DictConfig, memo: FingerprintMemo) -> dict[str, dict[str, str]]:
    """``{group: {path: digest}}`` for every stage group whose component reads files (hashed through
    ``memo``: :func:`memo_for`)."""
    from sphri.stages import RESULT_GROUPS

    exclude = frozenset(Path(str(d)).absolute() for d in (cfg.get("output_dir"), cfg.get("cache", {}).get("dir")) if d)
    out = {}
    for group in RESULT_GROUPS:  # tracking records a job, it computes nothing
        node = cfg.get(group)
        if not isinstance(node, DictConfig):
            continue
        fp = fingerprints(node, memo, exclude)
        if fp:
            out[group] = fp
    memo.save()
    return out
