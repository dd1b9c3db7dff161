"""Fuzz campaign, target 3: config overrides (issue 29, item 5).

Every scalar field of every component (the default config's, and each option of the stage groups'
``conf/<group>/*.yaml``) is set to a random value of the wrong type or range (text, lists, maps, NaN,
infinities, huge and negative numbers, interpolations, Hydra grammar characters). Composition must end
in sphri's one line (``ConfigError``) or a config holding the value given: never a traceback.
"""

from __future__ import annotations

import math
import subprocess
import sys

import pytest
import yaml
from fuzz_support import NAMED, SILENT, UNCHANGED, fuzz_settings
from hypothesis import given
from hypothesis import strategies as st
from omegaconf import OmegaConf

from sphri.config import CONF_DIR, ConfigError, component_node, compose

GROUPS = ("data", "contact", "surface", "layout", "encoder", "noise", "filter", "window", "model", "cv", "tracking")

#: Values of the wrong type or range for any field.
VALUES = st.one_of(
    st.sampled_from(
        [
            "abc",
            "-1",
            "0",
            "-0.5",
            "1e308",
            "1e-320",
            "inf",
            "-inf",
            "nan",
            ".nan",
            "[1,2]",
            "[]",
            "{a: 1}",
            "null",
            "true",
            "''",
            "99999999999999999999999",
            "${nope}",
            "${seed}",
            "glob(*)",
            "range(1,3)",
            "choice(1,2)",
            "'a b'",
            "1,2",
            "=",
            "x=y",
            "[",
            "}",
            "\\",
            "0x10",
            "1_000",
        ]
    ),
    st.integers(-(2**70), 2**70).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.text(alphabet=st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=10),
)


def _leaves(node, prefix=""):
    for k, v in node.items():
        if k in ("_target_", "defaults"):
            continue
        if isinstance(v, dict):
            yield from _leaves(v, f"{prefix}{k}.")
        elif not isinstance(v, list):
            yield f"{prefix}{k}"


def _fields() -> list[tuple[str | None, str]]:
    """(group option to choose or None, key): every scalar field of the schemas sphri ships."""
    out = [(None, k) for k in _leaves(OmegaConf.to_container(compose([], check=False), resolve=False))]
    for group in GROUPS:
        for path in sorted((CONF_DIR / group).glob("*.yaml")):  # the YAML on its schema: every field, written or not
            doc = OmegaConf.to_container(component_node(group, path.stem), resolve=False)
            out += [(f"{group}={path.stem}", f"{group}.{k}") for k in _leaves(doc)]
    return sorted(set(out), key=str)


FIELDS = _fields()


def _same(got, given_text: str) -> bool:
    try:
        want = yaml.safe_load(given_text)
    except yaml.YAMLError:
        want = given_text
    if got == want or str(got) == given_text or str(got) == str(want):
        return True
    try:
        a, b = float(got), float(want)
    except (TypeError, ValueError):
        return False
    return a == b or (math.isnan(a) and math.isnan(b))


@fuzz_settings(small=10, large=170)
@given(field=st.sampled_from(FIELDS), value=VALUES)
def test_wrong_values_for_every_schema_field(tally, field, value):
    choice, key = field
    overrides = ([choice] if choice else []) + [f"{key}={value}"]
    try:
        cfg = compose(overrides)
    except Exception as exc:  # noqa: BLE001 - judged: ConfigError's one line, or re-raised
        group = key.split(".")[0]
        tally.add(group, tally.named(group, exc))
        return
    got = OmegaConf.select(cfg, key, throw_on_missing=False)
    # an interpolation (${seed}) is replaced by what it names: OmegaConf's documented meaning
    v = UNCHANGED if _same(got, value) or value.strip().startswith("${") else SILENT
    tally.add(key.split(".")[0], v)
    assert v == UNCHANGED, f"{overrides}: composed with {key}={got!r}"
    assert v != NAMED


@pytest.mark.parametrize("override", ["layout.res=abc", "noise.p={a: 1}", "window.frames=1e308"])
def test_the_command_line_prints_one_line_not_a_traceback(override, tmp_path):
    """The CLI's own path (Hydra app + sphri's handler), in a subprocess: one line, exit 2, no traceback."""
    r = subprocess.run(
        [sys.executable, "-m", "sphri", override, f"output_dir={tmp_path}"],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert r.returncode == 2, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert "Traceback" not in r.stderr and len(lines) == 1 and "invalid config" in lines[0], r.stderr


@pytest.mark.parametrize("value", ["-1", "2", "99999999999999999999999"])
def test_a_number_for_a_boolean_field_is_refused_not_made_true(value):
    """Found by this campaign: ``encoder.binary=-1`` composed as ``encoder.binary=True`` (OmegaConf turns
    any integer into a boolean). Now one line: ``encoder.binary=-1 is invalid: must be true or false``."""
    with pytest.raises(ConfigError, match=rf"encoder\.binary={value} is invalid: must be true or false"):
        compose([f"encoder.binary={value}"])
    assert compose(["encoder.binary=0"]).encoder.binary is False  # 0 and 1 keep their meaning
