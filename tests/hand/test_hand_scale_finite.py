"""Every config range physical (issue 29, item 3): a non-finite hand scale is refused at composition."""

from __future__ import annotations

import os

import forked_cli
import pytest

from sphri.config import ConfigError, compose, require_range


@pytest.mark.parametrize("value", ["inf", "nan", "-inf"])
def test_non_finite_hand_scale_is_refused_at_composition(value):
    """Reproducer (issue 29): ``hand.scale=inf`` passed validation."""
    with pytest.raises(
        ConfigError,
        match=rf"hand\.scale={value.replace('inf', 'inf')}.* is invalid: must be a finite "
        r"number in \(0, inf\)",
    ):
        compose(["+debug=fast", f"hand.scale={value}"])


def test_every_range_refuses_non_finite_values():
    """The rule sits in ``require_range``, so every range-checked setting refuses NaN and inf."""
    require_range("x", 1.5, lo=0.0)
    for bad in (float("inf"), float("-inf"), float("nan")):
        with pytest.raises(ConfigError, match="must be a finite number"):
            require_range("x", bad, lo=None, hi=None)


def test_non_finite_hand_scale_is_one_line_and_exit_2_from_the_command_line(tmp_path):
    """Reproducer (issue 29), as a user types it: ``python -m sphri +debug=fast hand.scale=inf``."""
    env = {k: v for k, v in os.environ.items() if k != "HYDRA_FULL_ERROR"}
    run = forked_cli.run(["-m", "sphri", "+debug=fast", "hand.scale=inf"], tmp_path, env, 600)
    assert run.returncode == 2, run.stderr
    assert run.stderr.strip().splitlines() == [
        "sphri: invalid config: hand.scale=inf is invalid: must be a finite number in (0, inf)"
    ]
    assert not (tmp_path / "outputs" / "cache").exists()  # nothing ran
