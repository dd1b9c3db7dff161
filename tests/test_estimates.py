"""Every time a page of the guide or a message of sphri gives names the machine it was measured on (its CPU,
e.g. "2 shared AMD EPYC cores") and the date (2026-11-28): a bare "about 45-60 s" or "seconds-long" is
a promise no other machine keeps. Long steps show their real progress instead (sphri.progress)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PAGES = [
    REPO / "README.md",
    *sorted((REPO / "docs" / "tutorials").glob("*.md")),
    *sorted((REPO / "docs" / "how-to").glob("*.md")),
    *sorted((REPO / "docs" / "explanation").glob("*.md")),
    *(REPO / "docs" / name for name in ("ROBOTS.md", "CLUSTER.md", "development.md")),
]
#: Durations that are quantities of the data or a setting, not run times: (page, phrase).
FACTS = {
    ("docs/explanation/method.md", "45 ms latency"),  # the hand tracking's delay the generator models
    ("docs/explanation/what-sphri-answers.md", ">= 2 s without contact"),  # the episode gap setting
    ("docs/RELIABILITY.md", "not granted within 5 s"),  # the repair's lock timeout, a setting
}
#: Reference pages: their times are protocol and format facts (a 60 ms pulse), so only estimates count there.
REFERENCE_PAGES = [REPO / "docs" / name for name in ("PROTOCOLS.md", "RELIABILITY.md", "RECORDING_FORMAT.md")]
BENCHMARKS = REPO / "docs" / "BENCHMARKS.md"
DURATION = re.compile(
    r"(?<![\w.])\d+(?:[.,]\d+)?(?:\s*(?:-|to)\s*\d+(?:\.\d+)?)?\s*(?:s|sec|seconds|min|minutes|h|hours|ms|µs)\b"
    r"(?!\^)|\b(?:seconds|minutes|hours)-long\b|\ba few (?:seconds|minutes)\b",
    re.I,
)
#: An estimate in a message: "about 20 s", "takes 2 minutes", "seconds-long" (a data fact such as "8 s" is none).
ESTIMATE = re.compile(
    r"\b(?:about|takes?|took|under|within)\s+\d+(?:[.,]\d+)?(?:\s*(?:-|to)\s*\d+(?:\.\d+)?)?\s*"
    r"(?:s|sec|seconds|min|minutes|h|hours)\b|\b(?:seconds|minutes|hours)-long\b|\ba few (?:seconds|minutes)\b",
    re.I,
)
#: A machine named, or said plainly not to have been recorded (an old measurement keeps its date).
MACHINE = re.compile(r"\b(?:EPYC|Xeon|Ryzen|Core i\d|Apple M\d|H100|H200|A100)\b|CPU model not recorded")
DATE = re.compile(r"\b20\d\d-\d\d(?:-\d\d)?\b")


def unnamed(text: str, times: re.Pattern = DURATION) -> list[str]:
    """The paragraphs (runs of non-blank lines) of ``text`` that give a time (``times``) without a machine and a
    date. Inline code (`...`) is left out: it quotes commands and what they print (a progress line's real rate)."""
    out = []
    for para in re.split(r"\n\s*\n", text):
        plain = re.sub(r"`[^`]*`", "", re.sub(r"^\s*```.*$", "", para, flags=re.M))  # fences kept as text
        if times.search(plain) and not (MACHINE.search(para) and DATE.search(para)):
            out.append(para.strip())
    return out


def test_the_check_finds_a_bare_estimate_and_passes_a_named_one():
    assert unnamed("warmup (about 45-60 s on 2 cores)\n\nother") == ["warmup (about 45-60 s on 2 cores)"]
    assert unnamed("a seconds-long smoke run") and unnamed("the suite: 7 to 18 minutes") and unnamed("took 84 s")
    assert unnamed("took 84 s\non 2 shared AMD EPYC cores (2026-11-26)") == []
    assert unnamed("sync_interval_s seconds, 40 cm^2, a 5 mm pitch, 2026-11-26") == []
    assert unnamed("`[sweep 12/50 done; 3.1 min, ETA 9.8 min]`") == []  # a printed progress line
    assert unnamed("```bash\nsphri sweep   # 48 jobs: 31 min\n```")  # a fenced block's comment counts
    assert unnamed("compiling (about 20 s once)", ESTIMATE) and not unnamed("longest trial 69 s", ESTIMATE)


def test_every_time_on_a_newcomers_page_names_its_machine_and_date():
    bad = []
    for page in PAGES:
        name, text = str(page.relative_to(REPO)), page.read_text()
        for page_name, phrase in FACTS:
            if page_name == name:
                assert phrase in text, f"{name}: {phrase!r} is gone: drop it from FACTS"
                text = text.replace(phrase, "")
        bad += [f"{name}: {para[:160]!r}" for para in unnamed(text)]
    assert not bad, "a time without the machine and date it was measured on:\n" + "\n".join(bad)


def _without_facts(page: Path) -> str:
    name, text = str(page.relative_to(REPO)), page.read_text()
    for page_name, phrase in FACTS:
        if page_name == name:
            assert phrase in text, f"{name}: {phrase!r} is gone: drop it from FACTS"
            text = text.replace(phrase, "")
    return text


def test_reference_pages_give_no_bare_estimate():
    bad = [
        f"{page.relative_to(REPO)}: {para[:160]!r}"
        for page in REFERENCE_PAGES
        for para in unnamed(_without_facts(page), ESTIMATE)
    ]
    assert not bad, "an estimate without the machine and date it was measured on:\n" + "\n".join(bad)


def benchmark_sections_unnamed(text: str) -> list[str]:
    """The sections (a heading and its text, down to the next heading) of the benchmarks page that give a time
    without naming the machine and the date anywhere in the section: a section states its machine once."""
    sections = re.split(r"\n(?=#{1,4} )", text)
    return [s.splitlines()[0] for s in sections if unnamed(re.sub(r"\n\s*\n", "\n", s))]


def test_every_benchmark_section_names_its_machine_and_date():
    assert benchmark_sections_unnamed("## A\n\ntook 84 s\n\n## B\n\n2-core AMD EPYC, 2026-11-26\n\ntook 3 s") == [
        "## A"
    ]
    bad = benchmark_sections_unnamed(_without_facts(BENCHMARKS))
    assert not bad, "a benchmark section with a time and no machine and date:\n" + "\n".join(bad)


def _messages(tree: ast.AST):
    """The string constants of a module that are not docstrings."""
    docstrings = {
        id(node.body[0].value)
        for node in ast.walk(tree)
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
        and node.body
        and isinstance(node.body[0], ast.Expr)
        and isinstance(node.body[0].value, ast.Constant)
    }
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            yield node.lineno, node.value


def test_sphris_messages_give_no_bare_time_estimate():
    bad = []
    for path in sorted((REPO / "sphri").rglob("*.py")):
        for line, text in _messages(ast.parse(path.read_text())):
            if unnamed(text, ESTIMATE):
                bad.append(f"{path.relative_to(REPO)}:{line}: {text[:120]!r}")
    assert not bad, "a message with a time estimate and no machine or date:\n" + "\n".join(bad)
