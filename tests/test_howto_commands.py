"""The ```bash blocks of the how-to pages and of the first-job tutorial run as written.

Each block runs, in page order, as one bash script in a folder shared by the pages (their stage caches
too), with the ``sphri`` and ``mlflow`` of this environment first on the PATH. Every command must exit 0,
or the status its own comment names (``... exit 2``). A block that must not run here (a full-size sweep,
a server, a serial port) has ``<!-- not run: REASON -->`` on the line before it; a marker without a
reason fails. Where a page's commands are too slow at full size, the page has a debug-size block beside
them, which runs.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
#: first-job first: its debug-size jobs are the ones the requirement page's sweep then finds in the cache
PAGES = [REPO / "docs" / "tutorials" / "first-job.md", *sorted((REPO / "docs" / "how-to").glob("*.md"))]
MARKER = re.compile(r"^<!--\s*not run\s*(?::\s*(?P<reason>.*?))?\s*-->\s*$")
EXIT = re.compile(r"#.*\bexit (\d+)\b")


@dataclass(frozen=True)
class Block:
    line: int  # of the opening fence, 1-based
    body: str
    skip: str | None  # the reason a marker gives; "" for a marker without one; None: the block runs


def blocks(markdown: str) -> list[Block]:
    """The page's ```bash blocks with the not-run marker on the line before each (blank lines between allowed)."""
    out, lines = [], markdown.splitlines()
    i = 0
    while i < len(lines):
        if lines[i].strip() == "```bash":
            j = i + 1
            while j < len(lines) and lines[j].strip() != "```":
                j += 1
            k = i - 1
            while k >= 0 and not lines[k].strip():
                k -= 1
            m = MARKER.match(lines[k].strip()) if k >= 0 else None
            skip = None if m is None else (m.group("reason") or "").strip()
            out.append(Block(i + 1, "\n".join(lines[i + 1 : j]) + "\n", skip))
            i = j
        i += 1
    return out


def commands(body: str) -> list[str]:
    """A block's commands: continued lines joined, comment-only and blank lines dropped."""
    out, cur = [], ""
    for raw in body.splitlines():
        cur += raw.lstrip() if cur else raw
        if cur.rstrip().endswith("\\"):
            cur = cur.rstrip()[:-1].rstrip() + " "
            continue
        if cur.strip() and not cur.strip().startswith("#"):
            out.append(cur.strip())
        cur = ""
    return out


def script(cmds: list[str]) -> str:
    """A bash script that runs ``cmds`` in order and stops at the first one whose status is not the one
    its comment names (``exit N``), or 0, naming it."""
    lines = ["set -uo pipefail"]
    for cmd in cmds:
        want = EXIT.search(cmd)
        lines.append(cmd)
        lines.append(
            f'rc=$?; if [ "$rc" != {want.group(1) if want else 0} ]; then '
            f"echo {_quote('sphri-docs: exit ')}$rc{_quote(': ' + cmd)} >&2; exit 1; fi"
        )
    return "\n".join(lines) + "\n"


def _quote(text: str) -> str:
    return "'" + text.replace("'", "'\"'\"'") + "'"


def test_blocks_read_markers_and_need_a_reason():
    page = (
        "# t\n\n<!-- not run: needs a serial port -->\n```bash\nsphri skin live\n```\n\n"
        "```bash\nsphri a \\\n  b=1   # exit 2\n# a comment\n```\n\n<!-- not run -->\n\n```bash\nsphri c\n```\n"
        "```text\nsphri not-a-command\n```\n"
    )
    got = blocks(page)
    assert [(b.line, b.skip) for b in got] == [(4, "needs a serial port"), (8, None), (16, "")]
    assert commands(got[1].body) == ["sphri a b=1   # exit 2"]


def test_script_stops_at_a_command_with_the_wrong_status(tmp_path):
    def run(cmds: list[str]) -> subprocess.CompletedProcess:
        return subprocess.run(["bash", "-c", script(cmds)], capture_output=True, text=True, cwd=tmp_path)

    assert run(["true", "(exit 2)   # refused, exit 2", "echo done > it"]).returncode == 0
    assert (tmp_path / "it").read_text() == "done\n"
    bad = run(["true", "(exit 3)   # 'quoted', exit 2", "echo not > it"])
    assert bad.returncode == 1 and "sphri-docs: exit 3: (exit 3)   # 'quoted', exit 2" in bad.stderr
    assert run(["false"]).returncode == 1 and (tmp_path / "it").read_text() == "done\n"


def test_every_page_has_commands_and_every_skipped_block_says_why():
    for page in PAGES:
        found = blocks(page.read_text())
        assert found, f"{page}: no ```bash block"
        for b in found:
            assert b.skip != "", f"{page}:{b.line}: a not-run block needs a reason (<!-- not run: REASON -->)"
        assert any(b.skip is None for b in found), f"{page}: no block runs (give it a debug-size variant)"


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("howto")


@pytest.mark.parametrize("page", PAGES, ids=[p.stem for p in PAGES])
def test_page_commands_run_as_written(page, workdir):
    bin_dir = Path(sys.executable).parent
    env = {k: v for k, v in os.environ.items() if k != "MLFLOW_TRACKING_URI"}
    env["PATH"] = os.pathsep.join([str(bin_dir), env.get("PATH", "")])
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")])
    env["XDG_CACHE_HOME"] = str(workdir / "xdg")
    cmds = [c for b in blocks(page.read_text()) if b.skip is None for c in commands(b.body)]
    assert cmds
    t0 = time.perf_counter()
    done = subprocess.run(
        ["bash", "-c", script(cmds)], capture_output=True, text=True, cwd=workdir, env=env, timeout=600
    )
    out = done.stdout + done.stderr
    assert done.returncode == 0, f"{page.relative_to(REPO)} ({time.perf_counter() - t0:.0f} s):\n{out[-4000:]}"
