"""MkDocs hook: adds the generated reference pages (:mod:`sphri.docs_gen`) to the site at build time."""

from __future__ import annotations

import sys
from pathlib import Path

from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[1]


def on_files(files: Files, config) -> Files:
    if str(ROOT) not in sys.path:  # a checkout without `pip install -e .` still builds its own sphri's pages
        sys.path.insert(0, str(ROOT))
    from sphri.docs_gen import pages

    for uri, text in pages().items():
        files.append(File.generated(config, uri, content=text))
    return files
