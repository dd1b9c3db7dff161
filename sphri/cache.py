"""On-disk stage cache: content-addressed, atomic, checksummed, process-safe, no pickle.

An entry lives at ``<root>/<stage>/<key>.entry``. ``key`` is a hash of the
stage's config subtree, its inputs' keys, the content fingerprints of the
files it reads and the component's ``VERSION`` (:func:`stage_key`). The file
is ``MAGIC | blake2b(payload) | payload`` where the payload is an ``.npz``
(read with ``allow_pickle=False``): the value's arrays plus ``__meta__``, a
JSON document holding the stage, the key, the input files' fingerprints and
the value's structure (:mod:`sphri.codec`). Nothing in an entry can execute
code when it is read.

- Writes go to a temporary file in the same folder, then ``os.replace``:
  a reader never sees a half-written entry.
- An entry that fails its checksum, is not an npz, or does not decode into
  the stage's contract (another type, other fields, a class outside sphri)
  is logged, removed and recomputed, never used.
- A per-entry ``fcntl`` lock makes concurrent jobs (a parallel sweep)
  compute an entry once: the others wait and then read it.
- ``<root>/<stage>/by-path/<path_key>.json`` remembers, for the same stage
  config with files named by path only, which key and file fingerprints were
  last stored: when a file changed, the log names it.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import logging
import io
import os
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, TypeVar

import numpy as np

from sphri.codec import DecodeError, EncodeError, check_contract, decode, encode

log = logging.getLogger(__name__)

MAGIC = b"SPHRICACHE2\n"
SUFFIX = ".entry"
META = "__meta__"
_DIGEST = 32
T = TypeVar("T")


def stable_hash(obj: Any) -> str:
    """Hex digest (20 chars) of a JSON-able object, independent of dict order."""
    text = json.dumps(obj, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.blake2b(text.encode(), digest_size=10).hexdigest()


def stage_key(stage: str, version: str, config: Any, inputs: dict[str, str]) -> str:
    """Cache key of one stage: its name, component version, config and inputs' keys."""
    return stable_hash({"stage": stage, "version": version, "config": config, "inputs": inputs})


class CorruptEntry(RuntimeError):
    """A cache file failed its header or checksum."""


def _encode(value: Any, meta: dict[str, Any]) -> bytes:
    tree, arrays = encode(value)
    if META in arrays:  # pragma: no cover - array names are a0, a1, ...
        raise EncodeError(f"array name {META} is reserved")
    doc = json.dumps({**meta, "value": tree}, separators=(",", ":")).encode()
    buf = io.BytesIO()
    np.savez(buf, **arrays, **{META: np.frombuffer(doc, dtype=np.uint8)})
    payload = buf.getvalue()
    return MAGIC + hashlib.blake2b(payload, digest_size=_DIGEST).digest() + payload


def _decode(blob: bytes, path: Path) -> tuple[dict[str, Any], Any]:
    """``(meta, value)`` of an entry; raises :class:`CorruptEntry` or :class:`DecodeError`."""
    head = len(MAGIC)
    if len(blob) < head + _DIGEST or blob[:head] != MAGIC:
        raise CorruptEntry(f"{path}: not a sphri cache entry (bad header or truncated)")
    digest, payload = blob[head : head + _DIGEST], blob[head + _DIGEST :]
    if hashlib.blake2b(payload, digest_size=_DIGEST).digest() != digest:
        raise CorruptEntry(f"{path}: checksum mismatch (truncated or corrupted)")
    try:
        with np.load(io.BytesIO(payload), allow_pickle=False) as z:
            arrays = {name: z[name] for name in z.files}
    except (ValueError, OSError, zipfile.BadZipFile, EOFError) as exc:
        raise CorruptEntry(f"{path}: not an npz of plain arrays ({exc})") from None
    if META not in arrays:
        raise CorruptEntry(f"{path}: no {META} document")
    try:
        meta = json.loads(arrays.pop(META).tobytes().decode())
    except (UnicodeDecodeError, ValueError) as exc:
        raise CorruptEntry(f"{path}: unreadable {META} ({exc})") from None
    if not isinstance(meta, dict) or "value" not in meta:
        raise CorruptEntry(f"{path}: {META} has no value")
    return meta, decode(meta.pop("value"), arrays)


def write_entry(path: Path, value: Any, meta: dict[str, Any] | None = None) -> Path:
    """Write ``value`` to ``path`` as one checksummed entry (arrays + JSON, no pickle), atomically."""
    path = Path(path)
    blob = _encode(value, {"format": 2, **(meta or {})})
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(blob)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    return path


def read_entry(path: Path, contract: Any = None) -> tuple[dict[str, Any], Any]:
    """``(meta, value)`` of an entry written by :func:`write_entry`.

    Raises ``OSError`` when the file cannot be read, :class:`CorruptEntry` or
    :class:`~sphri.codec.DecodeError` (each naming ``path``) when it is not a
    valid entry or its value is not of ``contract``.
    """
    path = Path(path)
    meta, value = _decode(path.read_bytes(), path)
    check_contract(value, contract, str(path))
    return meta, value


@dataclass
class StageCache:
    """The cache under ``root``; ``enabled=False`` computes everything."""

    root: Path
    enabled: bool = True
    hits: list[str] = field(default_factory=list)
    misses: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.root = Path(self.root).resolve()

    def path(self, stage: str, key: str) -> Path:
        return self.root / stage / f"{key}{SUFFIX}"

    def _index_path(self, stage: str, path_key: str) -> Path:
        return self.root / stage / "by-path" / f"{path_key}.json"

    @contextlib.contextmanager
    def _lock(self, path: Path) -> Iterator[None]:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path.with_suffix(".lock"), "a+b") as fh:
            fcntl.flock(fh, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(fh, fcntl.LOCK_UN)

    def read(self, stage: str, key: str, contract: Any = None) -> tuple[bool, Any]:
        """(True, value) for a valid entry; (False, None) if absent, corrupt or not of ``contract``."""
        path = self.path(stage, key)
        try:
            blob = path.read_bytes()
        except FileNotFoundError:
            return False, None
        try:
            meta, value = _decode(blob, path)
            if meta.get("stage") != stage or meta.get("key") != key:
                raise DecodeError(f"{path}: holds stage {meta.get('stage')!r} key {meta.get('key')!r}")
            check_contract(value, contract, f"{path}: stage {stage}")
            return True, value
        except (CorruptEntry, DecodeError) as exc:
            log.warning("cache: discarding corrupt entry for stage %s (%s); recomputing", stage, exc)
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
            return False, None

    def write(self, stage: str, key: str, value: Any, files: dict[str, str] | None = None) -> Path:
        """Store ``value``; raises :class:`~sphri.codec.EncodeError` when it cannot be stored as arrays + JSON."""
        return write_entry(self.path(stage, key), value, {"stage": stage, "key": key, "files": files or {}})

    def changed_files(self, stage: str, path_key: str, key: str, files: dict[str, str]) -> list[str]:
        """Files whose content differs from the entry last stored for the same config and paths."""
        try:
            old = json.loads(self._index_path(stage, path_key).read_text())
        except (OSError, ValueError):
            return []
        if not isinstance(old, dict) or old.get("key") == key:
            return []
        before = old.get("files") or {}
        return sorted(p for p in set(files) | set(before) if files.get(p) != before.get(p))

    def _remember(self, stage: str, path_key: str, key: str, files: dict[str, str]) -> None:
        path = self._index_path(stage, path_key)
        with contextlib.suppress(OSError):
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=".idx.", suffix=".tmp", dir=path.parent)
            with os.fdopen(fd, "w") as fh:
                json.dump({"key": key, "files": files}, fh)
            os.replace(tmp, path)

    def get_or_compute(self, stage: str, key: str, compute: Callable[[], T], contract: Any = None,
                       files: dict[str, str] | None = None, path_key: str | None = None) -> T:
        """Return the cached value of (stage, key), computing and storing it if needed.

        ``contract``: what the value must be (see :func:`sphri.codec.check_contract`).
        ``files``: ``{path: fingerprint}`` of the files behind the value (recorded in
        the entry); with ``path_key`` (the key with files named by path only), a
        recomputation caused by a changed file logs which file.
        """
        if not self.enabled:
            self.misses.append(stage)
            return compute()
        found, value = self.read(stage, key, contract)
        if found:
            self.hits.append(stage)
            return value
        with self._lock(self.path(stage, key)):
            found, value = self.read(stage, key, contract)  # another process may have written it
            if found:
                self.hits.append(stage)
                return value
            if path_key is not None and files:
                changed = self.changed_files(stage, path_key, key, files)
                if changed:
                    log.info("stage %s: input file(s) changed since the cached entry: %s; recomputing",
                             stage, ", ".join(changed))
            value = compute()
            try:
                self.write(stage, key, value, files)
            except EncodeError as exc:
                log.warning("cache: stage %s output not cached (%s)", stage, exc)
            else:
                if path_key is not None:
                    self._remember(stage, path_key, key, files or {})
        self.misses.append(stage)
        return value


if __name__ == "__main__":  # python -m sphri.cache info|clear
    import sys

    from sphri.cache_cli import main

    sys.exit(main())
