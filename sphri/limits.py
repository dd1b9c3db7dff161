"""How much memory a job may plan to use: work estimated from its settings before it starts.

Settings that size a job's arrays (``data.participants``, a layout's taxel count, ``report n_boot``)
are checked against one limit before anything is allocated, where the inputs are known (most at
composition, so ``sphri validate`` refuses them too); the contact stage checks each link's mesh faces
and its query chunk when the robot is loaded (:func:`sphri.contact.stage.check_contact_memory`). The limit is the environment variable
``SPHRI_MAX_MEMORY_GIB`` (GiB) when set, else the memory available on this machine (``MemAvailable``).
A refusal gives the estimate, the limit and the setting to lower, and names ``SPHRI_MAX_MEMORY_GIB``
as the way to raise the limit.
"""

from __future__ import annotations

import math
import os

GIB = float(1 << 30)

#: The environment variable that sets the memory limit (GiB).
LIMIT_ENV = "SPHRI_MAX_MEMORY_GIB"


def available_memory_bytes() -> float | None:
    """``MemAvailable`` of /proc/meminfo (bytes), else free physical pages; None when unknown."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def memory_limit() -> tuple[float, str] | None:
    """(bytes, how the limit was set) or None when neither the variable nor the machine says."""
    text = os.environ.get(LIMIT_ENV, "").strip()
    if text:
        try:
            gib = float(text)
        except ValueError:
            gib = math.nan
        if math.isfinite(gib) and gib > 0:
            return gib * GIB, f"{LIMIT_ENV}={text}"
    avail = available_memory_bytes()
    if avail is None:
        return None
    return avail, "the memory available"


def over_limit(what: str, need_bytes: float) -> str | None:
    """None when ``need_bytes`` fits the limit; else the reason, ``'<what> would take X GiB, more than
    <limit> (Y GiB); ... raise SPHRI_MAX_MEMORY_GIB'`` (the caller names the setting to lower)."""
    limit = memory_limit()
    if limit is None or need_bytes <= limit[0]:
        return None
    size, why = limit
    return (
        f"{what} would take {need_bytes / GIB:.3g} GiB, more than {why} ({size / GIB:.3g} GiB); "
        f"lower it, or set {LIMIT_ENV} to raise the limit"
    )
