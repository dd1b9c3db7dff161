"""Functions of sphri stay short: one over 80 lines is a list of steps to name. The only ones over are numba
kernels (a call between compiled functions in a hot loop costs speed), listed here with their length at most;
the list may only shrink and may hold nothing else."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "sphri"
LIMIT = 80

#: ``path:function`` -> the most lines it may have: numba kernels only.
STILL_LONG = {
    "sphri/encode/raster.py:_raster_frame": 122,
    "sphri/contact/_kernels.py:_seg_tri": 109,
    "sphri/contact/_kernels.py:_nearest": 107,
    "sphri/contact/_kernels.py:query_rows": 90,
}


def long_functions(package: Path = PACKAGE) -> dict[str, int]:
    """``path:function`` -> lines, of every function of ``package`` longer than :data:`LIMIT` (the longest of
    a name repeated in one file)."""
    out: dict[str, int] = {}
    for path in sorted(package.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                key = f"{path.relative_to(package.parent).as_posix()}:{node.name}"
                if lines > LIMIT:
                    out[key] = max(lines, out.get(key, 0))
    return out


def test_no_new_function_over_80_lines_and_none_grows():
    found = long_functions()
    new = {k: v for k, v in found.items() if k not in STILL_LONG}
    grown = {k: (v, STILL_LONG[k]) for k, v in found.items() if k in STILL_LONG and v > STILL_LONG[k]}
    assert not new, f"functions over {LIMIT} lines (name their steps): {new}"
    assert not grown, f"listed long functions that grew (lines, allowed): {grown}"


def test_the_list_only_names_functions_still_long():
    split = sorted(set(STILL_LONG) - set(long_functions()))
    assert not split, f"now at most {LIMIT} lines: drop them from STILL_LONG: {split}"


def test_the_counter_sees_a_long_function(tmp_path):
    pkg = tmp_path / "sphri"
    pkg.mkdir()
    (pkg / "m.py").write_text("def f():\n" + "    x = 1\n" * LIMIT + "\n\ndef g():\n    return 1\n")
    assert long_functions(pkg) == {"sphri/m.py:f": LIMIT + 1}


def test_only_numba_kernels_are_allowed_to_be_long():
    """A function may stay over the limit only as a numba kernel (decorated ``@njit``)."""
    for key in STILL_LONG:
        path, name = key.split(":")
        tree = ast.parse((PACKAGE.parent / path).read_text())
        node = next(n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef) and n.name == name)
        decorators = [ast.unparse(d) for d in node.decorator_list]
        assert any(d.startswith("njit") for d in decorators), f"{key} is long and not a numba kernel: {decorators}"
