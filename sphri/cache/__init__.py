"""On-disk stage cache: content-addressed, atomic, checksummed, process-safe, no pickle.

An entry lives at ``<root>/<stage>/<key>.entry``. ``key`` is a hash of the
stage's config subtree, its inputs' keys, the content fingerprints of the
files it reads and the component's ``VERSION`` (:func:`stage_key`). The file
is ``MAGIC | plain digest | keyed digest | payload`` (:mod:`sphri.integrity`)
where the payload is an ``.npz`` (read with ``allow_pickle=False``): the
value's arrays plus ``__meta__``, a JSON document holding the stage, the key,
the input files' fingerprints and the value's structure (:mod:`sphri.codec`).
Nothing in an entry can execute code when it is read.

- The plain digest (BLAKE2b) catches damage; anyone who can write to the
  cache can recompute it. With a key (``SPHRI_CACHE_KEY`` or
  ``SPHRI_CACHE_KEY_FILE``, :func:`sphri.integrity.load_key`), every entry
  also carries an HMAC-SHA256, and an entry whose HMAC does not verify
  (written without the key, or crafted) is discarded and recomputed, never
  read: whoever can write to a shared cache can then make jobs recompute,
  not change their results.
- Entries of the previous format (``SPHRICACHE2``) are recomputed.

- Writes go to a temporary file in the same folder, then ``os.replace``:
  a reader never sees a half-written entry.
- An entry that fails its checksum or key, is not an npz, or does not decode
  into the stage's contract (another type, other fields, a class not among
  the data types sphri stores, values inconsistent with each other, e.g. a 3x3 confusion matrix
  for 8 gestures), or whose decoding fails in any other way (a 200,000-deep
  JSON document, an out-of-range number) is logged with its file, removed
  and recomputed, never used and never raised.
- A per-entry lock (``filelock``) makes concurrent jobs (a parallel sweep)
  compute an entry once: the others wait and then read it.
- ``<root>/<stage>/by-path/<path_key>.json`` remembers, for the same stage
  config with files named by path only, which key and file fingerprints were
  last stored: when a file changed, the log names it.
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import stat
import zipfile
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from sphri.codec import DecodeError, EncodeError, check_contract, decode, encode
from sphri.fsutil import write_atomic
from sphri.integrity import DIGEST_SIZE, FROM_ENV, NO_KEY, keyed_digest, keyed_ok, load_key, plain_digest, stable_hash

log = logging.getLogger(__name__)

MAGIC = b"SPHRICACHE3\n"
#: The previous format (one BLAKE2b over the payload, no key): recomputed.
OLD_MAGICS = (b"SPHRICACHE2\n",)
SUFFIX = ".entry"
META = "__meta__"
_DIGEST = DIGEST_SIZE
T = TypeVar("T")


def _key(key: Any) -> bytes | None:
    return load_key("cache") if key is FROM_ENV else key


def seal(payload: bytes, key: bytes | None = None) -> bytes:
    """An entry's bytes around ``payload``: magic, plain digest, keyed digest (zeros without a key)."""
    return MAGIC + plain_digest(MAGIC, payload) + keyed_digest(key, MAGIC, payload) + payload


def stage_key(stage: str, version: str, config: Any, inputs: Mapping[str, Any]) -> str:
    """Cache key of one stage: its name, component version, config and inputs (upstream keys, plain values)."""
    return stable_hash({"stage": stage, "version": version, "config": config, "inputs": inputs})


class CorruptEntry(RuntimeError):
    """A cache file failed its header or checksum."""


def _encode(value: Any, meta: dict[str, Any], key: bytes | None = None) -> bytes:
    tree, arrays = encode(value)
    if META in arrays:  # pragma: no cover - array names are a0, a1, ...
        raise EncodeError(f"array name {META} is reserved")
    doc = json.dumps({**meta, "value": tree}, separators=(",", ":")).encode()
    buf = io.BytesIO()
    # the stub's allow_pickle: bool keyword takes the **arrays (named a0, a1, ... and META)
    np.savez(buf, **arrays, **{META: np.frombuffer(doc, dtype=np.uint8)})  # type: ignore[arg-type]
    return seal(buf.getvalue(), key)


def _decode(blob: bytes, path: Path, key: bytes | None = None) -> tuple[dict[str, Any], Any]:
    """``(meta, value)`` of an entry; raises :class:`CorruptEntry` or :class:`DecodeError`
    (or, for a crafted entry, whatever decoding it raises: :meth:`StageCache.read` discards it)."""
    head = len(MAGIC)
    if blob[:head] in OLD_MAGICS:
        raise CorruptEntry(f"{path}: an entry of an older cache format (no digest over a key)")
    if len(blob) < head + 2 * _DIGEST or blob[:head] != MAGIC:
        raise CorruptEntry(f"{path}: not a sphri cache entry (bad header or truncated)")
    digest, keyed = blob[head : head + _DIGEST], blob[head + _DIGEST : head + 2 * _DIGEST]
    payload = blob[head + 2 * _DIGEST :]
    if plain_digest(MAGIC, payload) != digest:
        raise CorruptEntry(f"{path}: checksum mismatch (truncated or corrupted)")
    if not keyed_ok(key, keyed, MAGIC, payload):
        why = "written without the key" if keyed == NO_KEY else "its HMAC does not match the key"
        raise CorruptEntry(f"{path}: not signed with the configured cache key ({why})")
    try:
        with np.load(io.BytesIO(payload), allow_pickle=False) as z:
            arrays = {name: z[name] for name in z.files}
    except (ValueError, OSError, zipfile.BadZipFile, EOFError) as exc:
        raise CorruptEntry(f"{path}: not an npz of plain arrays ({exc})") from None
    if META not in arrays:
        raise CorruptEntry(f"{path}: no {META} document")
    try:
        meta = json.loads(arrays.pop(META).tobytes().decode())
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise CorruptEntry(f"{path}: unreadable {META} ({type(exc).__name__}: {exc})") from None
    if not isinstance(meta, dict) or "value" not in meta:
        raise CorruptEntry(f"{path}: {META} has no value")
    return meta, decode(meta.pop("value"), arrays)


def write_entry(path: Path, value: Any, meta: dict[str, Any] | None = None, key: Any = FROM_ENV) -> Path:
    """Write ``value`` to ``path`` as one checksummed entry (arrays + JSON, no pickle), atomically.

    ``key``: HMAC key (bytes), None for none, or the environment's (default).
    The file gets the mode the umask gives (not mkstemp's 0600)."""
    path = Path(path)
    blob = _encode(value, {"format": 3, **(meta or {})}, _key(key))
    write_atomic(path, blob, fsync=True)
    return path


def read_entry(path: Path, contract: Any = None, key: Any = FROM_ENV) -> tuple[dict[str, Any], Any]:
    """``(meta, value)`` of an entry written by :func:`write_entry`.

    Raises ``OSError`` when the file cannot be read, :class:`CorruptEntry` or
    :class:`~sphri.codec.DecodeError` (each naming ``path``) when it is not a
    valid entry, is not signed with ``key`` (when one is configured) or its
    value is not of ``contract``.
    """
    path = Path(path)
    mode = path.stat().st_mode  # OSError when missing: a miss
    if not stat.S_ISREG(mode):  # a FIFO blocks its reader until a writer comes, a device never ends
        raise CorruptEntry(f"{path}: not a regular file (mode {stat.filemode(mode)}); never read")
    try:
        meta, value = _decode(path.read_bytes(), path, _key(key))
    except (CorruptEntry, DecodeError, OSError):
        raise
    except Exception as exc:  # a crafted entry: whatever decoding raised, named
        raise CorruptEntry(f"{path}: does not decode ({type(exc).__name__}: {exc})") from None
    check_contract(value, contract, str(path))
    return meta, value


@dataclass
class StageCache:
    """The cache under ``root``; ``enabled=False`` computes everything."""

    root: Path
    enabled: bool = True
    hits: list[str] = field(default_factory=list)
    misses: list[str] = field(default_factory=list)
    key: Any = FROM_ENV
    """HMAC key of the entries (bytes), None for none, or FROM_ENV: ``SPHRI_CACHE_KEY(_FILE)``."""

    def __post_init__(self) -> None:
        self.root = Path(self.root).resolve()
        self.key = _key(self.key) if self.enabled else None

    def path(self, stage: str, key: str) -> Path:
        return self.root / stage / f"{key}{SUFFIX}"

    def _index_path(self, stage: str, path_key: str) -> Path:
        return self.root / stage / "by-path" / f"{path_key}.json"

    @contextlib.contextmanager
    def _lock(self, path: Path) -> Iterator[None]:
        from filelock import FileLock

        path.parent.mkdir(parents=True, exist_ok=True)
        with FileLock(path.with_suffix(".lock")):
            yield

    def read(self, stage: str, key: str, contract: Any = None) -> tuple[bool, Any]:
        """(True, value) for a valid entry; (False, None) if absent, corrupt or not of ``contract``."""
        path = self.path(stage, key)
        try:
            mode = path.stat().st_mode
            if not stat.S_ISREG(mode):  # a FIFO blocks its reader until a writer comes, a device never ends
                raise OSError(f"not a regular file (mode {stat.filemode(mode)}); never read")
            blob = path.read_bytes()
        except FileNotFoundError:
            return False, None
        except OSError as exc:  # a FIFO, a device, a link loop, an unreadable file: recomputed
            log.warning("cache: discarding unreadable entry for stage %s (%s: %s); recomputing", stage, path, exc)
            return False, None  # the new entry's rename takes its place
        try:
            meta, value = _decode(blob, path, self.key)
            if meta.get("stage") != stage or meta.get("key") != key:
                raise DecodeError(f"{path}: holds stage {meta.get('stage')!r} key {meta.get('key')!r}")
            check_contract(value, contract, f"{path}: stage {stage}")
            return True, value
        except Exception as exc:  # noqa: BLE001 - a crafted entry may raise anything while decoding: never fatal
            text = str(exc) if str(path) in str(exc) else f"{path}: {type(exc).__name__}: {exc}"
            log.warning("cache: discarding corrupt entry for stage %s (%s); recomputing", stage, text[:500])
            with contextlib.suppress(OSError):
                path.unlink()
            return False, None

    def write(self, stage: str, key: str, value: Any, files: dict[str, str] | None = None) -> Path:
        """Store ``value``; raises :class:`~sphri.codec.EncodeError` when it cannot be stored as arrays + JSON."""
        return write_entry(
            self.path(stage, key), value, {"stage": stage, "key": key, "files": files or {}}, key=self.key
        )

    def changed_files(self, stage: str, path_key: str, key: str, files: dict[str, str]) -> list[str]:
        """Files whose content differs from the entry last stored for the same config and paths."""
        index = self._index_path(stage, path_key)
        try:
            old = json.loads(index.read_text())
        except (OSError, ValueError, RecursionError):
            return []
        if not isinstance(old, dict) or old.get("key") == key:
            return []
        before = old.get("files") or {}
        if not isinstance(before, dict) or not all(isinstance(p, str) for p in before):
            log.warning("cache: ignoring malformed index %s (files is not a map of paths)", index)
            return []
        return sorted(p for p in set(files) | set(before) if files.get(p) != before.get(p))

    def _remember(self, stage: str, path_key: str, key: str, files: dict[str, str]) -> None:
        path = self._index_path(stage, path_key)
        with contextlib.suppress(OSError):
            write_atomic(path, json.dumps({"key": key, "files": files}).encode())

    def get_or_compute(
        self,
        stage: str,
        key: str,
        compute: Callable[[], T],
        contract: Any = None,
        files: dict[str, str] | None = None,
        path_key: str | None = None,
    ) -> T:
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
                    log.info(
                        "stage %s: input file(s) changed since the cached entry: %s; recomputing",
                        stage,
                        ", ".join(changed),
                    )
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
