"""The tracebacks left: an interpolation that does not resolve, an output folder no folder can be made
in, a JSON file nested too deeply for the reader, a misspelt ``_target_`` and non-ASCII overrides each
end in one line naming the value, exit 2 for a config (1 for a file), before anything is computed."""

from __future__ import annotations

import subprocess
from pathlib import Path

import forked_cli
import pytest

_one_line = forked_cli.one_line


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return forked_cli.run(["-m", *args], cwd, None, 300)


@pytest.mark.parametrize(
    "override, words",
    [
        # 83 lines of OmegaConf's InterpolationResolutionError
        (
            "output_dir=${oc.env:SPHRI_TEST_NOT_SET}",
            ("output_dir=${oc.env:SPHRI_TEST_NOT_SET}", "'SPHRI_TEST_NOT_SET'"),
        ),
        # Hydra's mkdir of the run folder: FileNotFoundError
        ("output_dir=/proc/x", ("output_dir=/proc/x", "no folder can be made in /proc")),
        # validate said "config OK", the run printed 43 lines of Hydra's instantiate error
        (
            "model._target_=sphri.models.rf.RandomForst",
            ("model._target_='sphri.models.rf.RandomForst'", "did you mean 'sphri.models.rf.RandomForest'"),
        ),
        # Hydra's lexer: LexerNoViableAltException over three lines, exit 1
        ("seed=é", ("override 'seed=é'", "non-ASCII character 'é'", "seed='é'")),
        ("encoder.rés=3", ("override 'encoder.rés=3'", "non-ASCII character 'é'", "keys are ASCII names")),
    ],
)
def test_each_is_one_line_before_any_stage(tmp_path: Path, override: str, words: tuple[str, ...]):
    if override.startswith("output_dir=/proc") and not Path("/proc/self").is_dir():
        pytest.skip("needs /proc")
    args = ["sphri", "+debug=fast", "tracking.enabled=false", override]
    if not override.startswith("output_dir"):
        args.append(f"output_dir={tmp_path / 'o'}")
    proc = _run(args, tmp_path)
    _one_line(proc, 2, "invalid config", *words)
    assert "computing" not in proc.stdout + proc.stderr


def test_validate_refuses_a_target_outside_the_registered_components(tmp_path: Path):
    proc = _run(["sphri", "validate", "model._target_=sphri.models.rf.RandomForst"], tmp_path)
    _one_line(proc, 2, "invalid config", "not a registered model component", "RandomForest")
    ok = _run(["sphri", "validate", "model._target_=sphri.models.rf.RandomForest"], tmp_path)
    assert ok.returncode == 0, ok.stderr[-2000:]


def _deep(path: Path, depth: int = 100_000) -> Path:
    path.write_text("[" * depth + "]" * depth)
    return path


def test_a_json_file_nested_too_deeply_is_one_line(tmp_path: Path):
    """A hand definition of 100k nested lists raised RecursionError in the reader."""
    deep = _deep(tmp_path / "hand.json")
    args = ["sphri", "+debug=fast", "tracking.enabled=false", "cache.enabled=false", f"hand.definition_path={deep}"]
    proc = _run([*args, f"output_dir={tmp_path / 'o'}"], tmp_path)
    _one_line(proc, 1, "hand error", str(deep), "nested too deeply")


def test_a_manifest_nested_too_deeply_is_a_manifest_error(tmp_path: Path):
    from sphri.data.format import ManifestError, read_manifest

    with pytest.raises(ManifestError, match="nested too deeply"):
        read_manifest(_deep(tmp_path / "manifest.json"))
