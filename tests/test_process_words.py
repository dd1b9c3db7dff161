"""The code, the docs and the README say what sphri does, not how it came to be: no issue numbers, no
"this session", no "stop 3". A planted phrase is caught, in a string and in a file."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: Words about the project's own development, not about what the code does.
PROCESS_WORDS = re.compile(
    r"""
    \bissues?\s?\#?\s?\d+                                   # issue 12, issue #12, issues 16
    | \bwhen\ issue\b                                       # when issue 19 was filed
    | \bsince\ issue\b
    | \b(?:this|a\ later|an\ earlier|a\ previous|the\ previous|last)\ session\b
    | \bstop\ \#?\d+\b                                      # stop 3
    | \b(?:PR|pull\ request)\s?\#\d+
    | \bwork\ in\ progress\b
    | \breview\ mend\b
    """,
    re.IGNORECASE | re.VERBOSE,
)

#: What is scanned: the package, the documentation and the README (text files only).
SCANNED = ("sphri", "docs", "README.md", "CHANGELOG.md", "mkdocs.yml")
TEXT_SUFFIXES = {".py", ".md", ".yaml", ".yml", ".j2", ".html", ".txt", ".toml", ".json", ".csv", ".mplstyle"}


def process_words(text: str) -> list[tuple[int, str]]:
    """``(line number, phrase)`` of every process phrase in ``text``."""
    return [(n, m.group(0)) for n, line in enumerate(text.splitlines(), 1) for m in PROCESS_WORDS.finditer(line)]


def scan(paths: list[Path]) -> list[str]:
    """``file:line: phrase`` for every process phrase in the text files under ``paths``."""
    files: list[Path] = []
    for p in paths:
        if p.is_dir():
            files += sorted(f for f in p.rglob("*") if f.is_file() and f.suffix in TEXT_SUFFIXES)
        elif p.is_file():
            files.append(p)
    out = []
    for f in files:
        if "__pycache__" in f.parts:
            continue
        for n, phrase in process_words(f.read_text(errors="replace")):
            out.append(f"{f.relative_to(ROOT) if f.is_relative_to(ROOT) else f}:{n}: {phrase!r}")
    return out


def test_no_process_words_in_code_docs_and_readme():
    found = scan([ROOT / p for p in SCANNED])
    assert not found, "words about the project's history; say what the code does instead:\n" + "\n".join(found)


def test_a_planted_issue_number_is_caught_in_a_string():
    assert process_words("The retry loop (issue 12) stops after three tries.") == [(1, "issue 12")]
    for planted in ("see issue #31", "measured when issue 19 was filed", "in this session", "stop 4", "Issue 7:"):
        assert process_words(f"text\n{planted}\n"), planted
    for fine in ("an issue with the port", "the sessions folder", "a session's episodes", "stop the recorder"):
        assert process_words(fine) == [], fine


def test_a_planted_issue_number_is_caught_in_a_file(tmp_path):
    clean = tmp_path / "clean.md"
    clean.write_text("# Page\n\nThe recorder writes every frame as it is read.\n")
    assert scan([tmp_path]) == []
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "notes.py").write_text('"""Docstring."""\n\n# frames are fsynced (issue 12)\nX = 1\n')
    found = scan([tmp_path])
    assert len(found) == 1 and found[0].endswith("notes.py:3: 'issue 12'"), found
