"""``sphri cache info|clear [STAGE ...]``: see and trim the stage cache, never the MLflow store.

::

    sphri cache info                          # entries and size per stage under outputs/cache
    sphri cache info dir=/shared/sphri/cache  # another cache folder
    sphri cache clear evaluate                # drop one stage's entries (recomputed when needed)
    sphri cache clear older_than_days=14      # drop entries not read or written for two weeks
    sphri cache clear                         # drop every entry (asks nothing: it is only a cache)

Arguments are ``key=value`` (``dir``, default ``outputs/cache``; ``older_than_days``) plus stage names
(:class:`CacheArgs`). Entries are removed under their lock, so a job computing the same entry is not
disturbed; orphan lock and temporary files go with them. Runs, reports and ``mlflow.db`` are never
touched (``make clean`` removes everything). Links inside the cache (a stage
folder, an entry, an index folder) are never followed, so nothing outside it
is removed.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Literal

from sphri.args import ArgsError, arg
from sphri.cache import SUFFIX


class CacheCliError(ArgsError):
    """A bad argument of ``sphri cache``: a folder or stage that is not there."""


def _days(value: float | None) -> str | None:
    return "must be >= 0" if value is not None and value < 0 else None


@dataclasses.dataclass
class CacheArgs:
    action: Literal["info", "clear"] = arg(
        positional=True, metavar="info|clear", help="info: entries and size per stage; clear: remove entries"
    )
    stages: list[str] = arg([], positional=True, metavar="STAGE", help="stages to show or clear (default: every stage)")
    dir: Path = arg(Path("outputs/cache"), help="the cache folder")
    older_than_days: float | None = arg(
        None, check=_days, help="clear only the entries not read or written for this many days"
    )

    def __post_init__(self) -> None:
        if self.older_than_days is not None and self.action != "clear":
            raise ValueError(f"older_than_days={self.older_than_days:g} is only for clear")


def _entries(root: Path, stages: list[str]) -> dict[str, list[Path]]:
    if not root.is_dir():
        raise CacheCliError(f"dir={root}: no cache folder there")
    # links are never followed: a stage folder or an entry that is a link leads out of the cache
    present = sorted(p.name for p in root.iterdir() if _real_dir(p))
    links = [s for s in stages if (root / s).is_symlink()]
    if links:
        raise CacheCliError(f"{root / links[0]} is a link; links in the cache are never followed")
    unknown = [s for s in stages if s not in present]
    if unknown:
        raise CacheCliError(f"no stage {unknown} in {root}; stages there: {', '.join(present) or 'none'}")
    # only regular files are entries: a folder someone named *.entry is neither counted nor removed
    return {s: sorted(p for p in (root / s).glob(f"*{SUFFIX}") if _real_file(p)) for s in (stages or present)}


def _real_dir(p: Path) -> bool:
    return p.is_dir() and not p.is_symlink()


def _real_file(p: Path) -> bool:
    return p.is_file() and not p.is_symlink()


def _human(n: float) -> str:
    for unit in ("B", "kB", "MB"):
        if n < 1024:
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} GB"


def info(root: Path, stages: list[str]) -> str:
    lines = [f"stage cache {root.resolve()}:"]
    total = 0
    for stage, paths in _entries(root, stages).items():
        size = sum(p.stat().st_size for p in paths)
        total += size
        age = ""
        if paths:
            newest = max(p.stat().st_mtime for p in paths)
            age = f", newest {(time.time() - newest) / 86400:.1f} days ago"
        lines.append(f"  {stage:<10} {len(paths):>5} entries  {_human(size):>9}{age}")
    lines.append(f"  {'total':<10} {'':>5}          {_human(total):>9}")
    return "\n".join(lines)


def clear(root: Path, stages: list[str], older_than_days: float | None = None) -> tuple[int, int]:
    """Remove entries (of ``stages``, or all; only those older than the limit if given): (count, bytes)."""
    from filelock import FileLock

    cutoff = None if older_than_days is None else time.time() - older_than_days * 86400
    n = freed = 0
    for stage, paths in _entries(root, stages).items():
        for path in paths:
            st = path.stat()
            if cutoff is not None and max(st.st_mtime, st.st_atime) > cutoff:
                continue
            lock = path.with_suffix(".lock")
            if lock.is_symlink():  # a lock file is opened for writing: never through a link
                lock.unlink()
            with FileLock(lock):  # the entry's own lock: a job writing it finishes first
                path.unlink(missing_ok=True)
            lock.unlink(missing_ok=True)
            n, freed = n + 1, freed + st.st_size
        if cutoff is None:
            by_path = root / stage / "by-path"
            index = sorted(by_path.glob("*.json")) if _real_dir(by_path) else []
            for junk in [*(root / stage).glob(".*.tmp"), *index]:
                if _real_file(junk):
                    junk.unlink(missing_ok=True)
    return n, freed


def command(args: CacheArgs) -> int:
    """See (info) or trim (clear) the stage cache; runs, reports and mlflow.db are never touched."""
    if args.action == "info":
        print(info(args.dir, args.stages))
    else:
        n, freed = clear(args.dir, args.stages, args.older_than_days)
        print(f"removed {n} entries ({_human(freed)}) from {args.dir.resolve()}")
    return 0
