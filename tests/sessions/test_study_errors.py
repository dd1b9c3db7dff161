"""Session and priors file errors are one line naming the file (sphri.errors), in the study's command."""

from __future__ import annotations


def test_bad_priors_and_session_files_are_one_line(tmp_path, study_error_line):
    priors = tmp_path / "priors.yaml"
    priors.write_text("tail_s: 2.5\nbase_speed_m_s: 0.25\nscenarios:\n  S1: {start_positions: [moon]}\n")
    sessions = tmp_path / "sessions"
    sessions.mkdir()
    (sessions / "sessions.json").write_text("{not json")
    for overrides, needle in (
        ((f"data.priors={priors}",), str(priors)),
        (("data=sessions", f"data.root={sessions}"), str(sessions / "sessions.json")),
    ):
        error = study_error_line(*overrides)
        assert "data error" in error and needle in error, error
