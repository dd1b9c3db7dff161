"""On-disk stage cache: content-addressed, atomic, checksummed, process-safe.

An entry lives at ``<root>/<stage>/<key>.pkl``. ``key`` is a hash of the
stage's config subtree, its inputs' keys and the component's ``VERSION``
(:func:`stage_key`). The file is ``MAGIC | blake2b(payload) | payload``
where the payload is a pickle (protocol 5, numpy arrays stored raw).

- Writes go to a temporary file in the same folder, then ``os.replace``:
  a reader never sees a half-written entry.
- A truncated or corrupted entry fails its checksum: it is logged, removed
  and recomputed, never used.
- A per-entry ``fcntl`` lock makes concurrent jobs (a parallel sweep)
  compute an entry once: the others wait and then read it.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import logging
import os
import pickle
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, TypeVar

log = logging.getLogger(__name__)

MAGIC = b"SPHRICACHE1\n"
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


def _encode(value: Any) -> bytes:
    payload = pickle.dumps(value, protocol=5)
    return MAGIC + hashlib.blake2b(payload, digest_size=_DIGEST).digest() + payload


def _decode(blob: bytes, path: Path) -> Any:
    head = len(MAGIC)
    if len(blob) < head + _DIGEST or blob[:head] != MAGIC:
        raise CorruptEntry(f"{path}: not a sphri cache entry (bad header or truncated)")
    digest, payload = blob[head : head + _DIGEST], blob[head + _DIGEST :]
    if hashlib.blake2b(payload, digest_size=_DIGEST).digest() != digest:
        raise CorruptEntry(f"{path}: checksum mismatch (truncated or corrupted)")
    return pickle.loads(payload)


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
        return self.root / stage / f"{key}.pkl"

    @contextlib.contextmanager
    def _lock(self, path: Path) -> Iterator[None]:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path.with_suffix(".lock"), "a+b") as fh:
            fcntl.flock(fh, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(fh, fcntl.LOCK_UN)

    def read(self, stage: str, key: str) -> tuple[bool, Any]:
        """(True, value) for a valid entry; (False, None) if absent or corrupt."""
        path = self.path(stage, key)
        try:
            blob = path.read_bytes()
        except FileNotFoundError:
            return False, None
        try:
            return True, _decode(blob, path)
        except (CorruptEntry, pickle.UnpicklingError, EOFError, AttributeError, ImportError) as exc:
            log.warning("cache: discarding corrupt entry for stage %s (%s); recomputing", stage, exc)
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
            return False, None

    def write(self, stage: str, key: str, value: Any) -> Path:
        path = self.path(stage, key)
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{key}.", suffix=".tmp", dir=path.parent)
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(_encode(value))
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, path)
        except BaseException:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
            raise
        return path

    def get_or_compute(self, stage: str, key: str, compute: Callable[[], T]) -> T:
        """Return the cached value of (stage, key), computing and storing it if needed."""
        if not self.enabled:
            self.misses.append(stage)
            return compute()
        found, value = self.read(stage, key)
        if found:
            self.hits.append(stage)
            return value
        with self._lock(self.path(stage, key)):
            found, value = self.read(stage, key)  # another process may have written it
            if found:
                self.hits.append(stage)
                return value
            value = compute()
            self.write(stage, key, value)
        self.misses.append(stage)
        return value
