"""Outputs that never mix with or silently replace what is there, and commands that never reach outside
their folders: ``sphri synthesize``/``sphri export`` on an existing target, ``sphri cache clear`` through
a link, ``sphri coverage out=`` holding the MLflow store or an earlier run's files."""

from __future__ import annotations

import os

import pytest

from sphri.command import main as sphri_main

SMALL = ["+debug=fast", "data.participants=2", "data.repetitions=1", "data.regions=[arm]"]


def _line(err: str) -> str:
    (line,) = [ln for ln in err.splitlines() if ln.startswith("sphri")]
    return line


@pytest.mark.parametrize("what", ["gestures", "sessions"])
def test_synthesize_into_an_existing_folder_is_refused_before_generating(what, tmp_path, capsys, monkeypatch):
    """``sphri synthesize out=EXISTING`` wrote the new dataset's files among the old ones (the mix then
    loads without a word): refused in one line naming ``out`` and ``overwrite=true``, nothing generated."""
    import sphri.data.synthetic
    import sphri.sessions.synthetic

    def refuse(*_a, **_k):
        raise AssertionError("generating started")

    monkeypatch.setattr(sphri.data.synthetic.SyntheticData, "load", refuse)
    monkeypatch.setattr(sphri.sessions.synthetic.SyntheticSessions, "load", refuse)
    out = tmp_path / "ds"
    out.mkdir()
    (out / "kept.txt").write_text("an earlier dataset\n")
    code = sphri_main(["synthesize", f"what={what}", f"out={out}", "+debug=fast"])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err, err
    line = _line(err)
    assert f"out={out} is invalid: {out} exists and is not empty" in line and "overwrite=true" in line, line
    assert [p.name for p in out.iterdir()] == ["kept.txt"]


def test_synthesize_with_overwrite_replaces_the_folder_whole(tmp_path, capsys):
    out = tmp_path / "ds"
    out.mkdir()
    (out / "kept.txt").write_text("an earlier dataset\n")
    (out / "arm").mkdir()
    (out / "arm" / "participant_09").mkdir()  # a participant the new dataset does not have
    assert sphri_main(["synthesize", f"out={out}", "overwrite=true", *SMALL]) == 0
    names = sorted(p.name for p in out.iterdir())
    assert "kept.txt" not in names and "assets" in names, names
    assert sorted(p.name for p in (out / "arm").iterdir()) == ["participant_01", "participant_02"]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")], "no temporary folder left beside out"


def test_replace_dir_leaves_the_target_untouched_when_writing_fails(tmp_path):
    from sphri.fsutil import replace_dir

    target = tmp_path / "t"
    target.mkdir()
    (target / "old").write_text("old")
    with pytest.raises(RuntimeError), replace_dir(target) as fresh:
        (fresh / "new").write_text("new")
        raise RuntimeError("writing failed")
    assert [p.name for p in target.iterdir()] == ["old"] and sorted(os.listdir(tmp_path)) == ["t"]
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "precious").write_text("x")
    target.rename(tmp_path / "t0")
    target.symlink_to(outside)  # a link at out: replaced as a name, never followed
    with replace_dir(target) as fresh:
        (fresh / "new").write_text("new")
    assert not target.is_symlink() and [p.name for p in target.iterdir()] == ["new"]
    assert (outside / "precious").read_text() == "x"


def test_into_dir_writes_into_an_empty_target_and_replaces_a_full_one_only_on_success(tmp_path):
    from sphri.fsutil import into_dir, moved

    fresh_target = tmp_path / "new"
    with into_dir(fresh_target) as d:
        assert d == fresh_target and d.is_dir()  # absent (or empty): written in place
    full = tmp_path / "full"
    full.mkdir()
    (full / "old").write_text("old")
    with pytest.raises(RuntimeError), into_dir(full) as d:
        assert d != full
        (d / "new").write_text("new")
        raise RuntimeError("writing failed")
    assert [p.name for p in full.iterdir()] == ["old"]  # untouched by a failed run
    with into_dir(full) as d:
        (d / "new").write_text("new")
        paths = [d / "new"]
    assert [p.name for p in full.iterdir()] == ["new"] and moved(paths, d, full) == [full / "new"]
    assert sorted(os.listdir(tmp_path)) == ["full", "new"], "no temporary folder left beside the target"


def test_runs_started_in_the_same_second_never_share_a_default_folder(tmp_path, monkeypatch):
    """The default ``out`` of ``sphri coverage`` and of the scenario study is named by the second: a second run in
    that second got the same folder (then its files replaced the first run's); each now gets its own."""
    import time as time_module

    from sphri.fsutil import new_run_dir

    monkeypatch.setattr(time_module, "strftime", lambda fmt, *a: "2026-12-03_07-16-11")
    (tmp_path / "cov" / "2026-12-03_07-16-11_2").mkdir(parents=True)  # a name already taken, empty or not
    first, second, third = (new_run_dir(tmp_path / "cov") for _ in range(3))
    assert [first.name, second.name, third.name] == [
        "2026-12-03_07-16-11",
        "2026-12-03_07-16-11_3",
        "2026-12-03_07-16-11_4",
    ]
    assert all(p.is_dir() and not any(p.iterdir()) for p in (first, second, third))


@pytest.mark.parametrize("study", [False, True], ids=["link", "scenario_study"])
def test_coverage_into_a_folder_holding_files_is_refused_before_computing(study, tmp_path, capsys, monkeypatch):
    """``sphri coverage out=EXISTING`` wrote its files among an earlier run's (a ``by=gesture`` run's maps stayed
    beside a ``by=participant`` run's) and logged them all as the new run's MLflow artifacts: refused in one line
    naming ``out`` and ``overwrite=true``, before anything is computed, the folder untouched."""
    import sphri.pipeline
    from sphri.coverage import main

    def refuse(*_a, **_k):
        raise AssertionError("computing started")

    monkeypatch.setattr(sphri.pipeline, "make_pipeline", refuse)
    out = tmp_path / "cov"
    out.mkdir()
    (out / "density_hit.npz").write_text("an earlier run's map\n")
    argv = ["+experiment=scenario_study"] * study + ["+debug=fast", f"output_dir={tmp_path / 'o'}", f"out={out}"]
    code = main([*argv, "mlflow=false"])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err, err
    line = _line(err)
    assert f"out={out} is invalid: {out} exists and is not empty" in line and "overwrite=true" in line, line
    assert [p.name for p in out.iterdir()] == ["density_hit.npz"]


def test_export_onto_an_existing_model_file_is_refused_before_training(tmp_path, capsys, monkeypatch):
    """``sphri export out=EXISTING.sphrimodel`` replaced the file: refused in one line before training,
    unless ``overwrite=true``."""
    import sphri.pipeline
    from sphri.export import train

    class Trained(Exception):
        pass

    def refuse(*_a, **_k):
        raise Trained

    monkeypatch.setattr(sphri.pipeline, "make_pipeline", refuse)
    model = tmp_path / "rf.sphrimodel"
    model.write_bytes(b"an earlier model")
    code = train.main([f"out={model}", "+debug=fast"])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err, err
    line = _line(err)
    assert f"out={model} is invalid: {model} exists; give another name, or overwrite=true" in line, line
    assert model.read_bytes() == b"an earlier model"
    with pytest.raises(Trained):  # overwrite=true: past the check, training starts
        train.main([f"out={model}", "overwrite=true", "+debug=fast"])


def test_cache_clear_never_follows_a_link_out_of_the_cache(tmp_path, capsys):
    """A stage folder (or its by-path index) that is a link to another folder: ``sphri cache clear``
    deleted the files there. Links are left alone; only the cache's own entries go."""
    from sphri.cache.__init__ import SUFFIX

    root = tmp_path / "cache"
    (root / "evaluate" / "by-path").mkdir(parents=True)
    (root / "evaluate" / f"k{SUFFIX}").write_bytes(b"entry")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    precious = [elsewhere / f"results{SUFFIX}", elsewhere / "notes.json"]
    for p in precious:
        p.write_text("not the cache's\n")
    (root / "data").symlink_to(elsewhere)
    (root / "contact").mkdir()
    (root / "contact" / "by-path").symlink_to(elsewhere)
    (root / "contact" / f"e{SUFFIX}").symlink_to(elsewhere / f"results{SUFFIX}")
    assert sphri_main(["cache", "clear", f"dir={root}"]) == 0
    assert all(p.read_text() == "not the cache's\n" for p in precious)
    assert not (root / "evaluate" / f"k{SUFFIX}").exists()
    assert sphri_main(["cache", "clear", "data", f"dir={root}"]) == 2
    assert "is a link; links in the cache are never followed" in capsys.readouterr().err
    assert all(p.exists() for p in precious)


@pytest.mark.parametrize("where", ["output_dir", "above", "inside"])
def test_coverage_out_holding_the_mlflow_store_is_refused(where, tmp_path, capsys, monkeypatch):
    """``sphri coverage out=O output_dir=O`` logged every file of ``out`` as the run's artifacts, the
    MLflow artifacts folder included (hundreds of MB, then ``[Errno 36] File name too long``): refused
    before computing, naming the folder."""
    import sphri.pipeline
    from sphri.coverage import main

    def refuse(*_a, **_k):
        raise AssertionError("computing started")

    monkeypatch.setattr(sphri.pipeline, "make_pipeline", refuse)
    base = tmp_path / "o"
    out = {"output_dir": base, "above": tmp_path, "inside": base / "mlartifacts" / "cov"}[where]
    code = main(["+debug=fast", f"output_dir={base}", f"out={out}"])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err, err
    line = _line(err)
    assert f"out={out} is invalid: " in line and str(base / "m") in line, line


def test_an_out_that_is_a_dangling_link_is_refused(tmp_path):
    """A folder written at a link to nowhere lands wherever the link points (or fails after computing)."""
    from sphri.config import ConfigError, check_output_dir

    out = tmp_path / "out"
    out.symlink_to(tmp_path / "elsewhere" / "data")
    with pytest.raises(ConfigError, match=r"out=.* is a link to .*elsewhere/data, which does not exist"):
        check_output_dir(str(out), key="out", overwrite=False)
    assert not (tmp_path / "elsewhere").exists()
