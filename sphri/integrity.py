"""Digests of the files sphri writes and reads back (stage cache entries, model files): plain and keyed.

Each file carries two 32-byte digests over *everything it holds* (header and
payload, each framed by its length so bytes cannot move between them):

- a **plain** digest, BLAKE2b-256: catches truncation and corruption, but
  anyone can recompute it, so it does not tell who wrote the file;
- a **keyed** digest, HMAC-SHA256 with a secret key, or 32 zero bytes when
  the writer had no key: only a holder of the key can write a file that
  verifies.

When a key is configured, a reader refuses a file whose keyed digest does
not verify (written without the key, with another key, or crafted): a cache
entry is discarded and recomputed, a model file is refused. Without a key,
the keyed digest is not checked (the plain one always is).

Keys come from the environment, never from a config file that would be
logged: ``SPHRI_CACHE_KEY`` (the key itself) or ``SPHRI_CACHE_KEY_FILE`` (a
file holding it) for the stage cache, ``SPHRI_MODEL_KEY`` /
``SPHRI_MODEL_KEY_FILE`` for model files. A key file's bytes are used
stripped of surrounding whitespace; an empty or unreadable key is a
:class:`~sphri.config.ConfigError` naming the variable.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import struct
from typing import Any

DIGEST_SIZE = 32
#: The keyed digest of a file written without a key.
NO_KEY = bytes(DIGEST_SIZE)
#: Environment variables holding each purpose's key (or a file with it: the same name + ``_FILE``).
KEY_ENV = {"cache": "SPHRI_CACHE_KEY", "model": "SPHRI_MODEL_KEY"}


class _FromEnv:
    def __repr__(self) -> str:
        return "FROM_ENV"


#: Default of the ``key`` arguments of the cache and the model files: the key in the environment for that
#: purpose (:func:`load_key`), if any.
FROM_ENV: Any = _FromEnv()


def stable_hash(obj: Any) -> str:
    """Hex digest (20 chars) of a JSON-able object, independent of dict order (cache keys, sweep hashes)."""
    text = json.dumps(obj, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.blake2b(text.encode(), digest_size=10).hexdigest()


def plain_digest(*parts: bytes) -> bytes:
    """BLAKE2b-256 of the length-framed ``parts``."""
    h = hashlib.blake2b(digest_size=DIGEST_SIZE)
    for p in parts:
        h.update(struct.pack("<Q", len(p)))
        h.update(p)
    return h.digest()


def keyed_digest(key: bytes | None, *parts: bytes) -> bytes:
    """HMAC-SHA256 of the length-framed ``parts`` with ``key``; :data:`NO_KEY` when ``key`` is None."""
    if key is None:
        return NO_KEY
    h = hmac.new(key, digestmod=hashlib.sha256)
    for p in parts:
        h.update(struct.pack("<Q", len(p)))
        h.update(p)
    return h.digest()


def keyed_ok(key: bytes | None, stored: bytes, *parts: bytes) -> bool:
    """Whether ``stored`` is the keyed digest of ``parts`` (always True when no key is configured)."""
    if key is None:
        return True
    return stored != NO_KEY and hmac.compare_digest(stored, keyed_digest(key, *parts))


def load_key(purpose: str) -> bytes | None:
    """The key configured for ``purpose`` ("cache" or "model") in the environment, or None."""
    from sphri.config import ConfigError

    name = KEY_ENV[purpose]
    value = os.environ.get(name)
    file = os.environ.get(f"{name}_FILE")
    if value and file:
        raise ConfigError(f"{name} and {name}_FILE are both set; set one")
    if value:
        return value.encode()
    if file:
        try:
            with open(file, "rb") as fh:
                key = fh.read().strip()
        except OSError as exc:
            raise ConfigError(f"{name}_FILE={file}: cannot read the key ({exc.strerror or exc})") from None
        if not key:
            raise ConfigError(f"{name}_FILE={file}: the key file is empty")
        return key
    if value == "":
        raise ConfigError(f"{name} is set but empty; unset it or give a key")
    return None
