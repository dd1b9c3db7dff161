"""Validation that covers everything (issue 16, items 5 and 6): unknown keys, regions, degenerate
meshes, an unwritable cache.dir, chance level, LOSO on fewer participants, one clean error line."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import forked_cli
import numpy as np
import pandas as pd
import pytest

from sphri.config import ConfigError, compose
from sphri.types import GESTURES, CVResult, FoldResult, TaxelGeometry, WindowedFrames

REPO = Path(__file__).resolve().parent.parent


# ------------------------------------------------------------ keys and regions
@pytest.mark.parametrize(
    "override, match",
    [
        ("+model.n_estimator=5", r"model\.n_estimator is not a known key \(did you mean n_estimators\?\)"),
        ("+seeed=3", r"seeed is not a known key \(did you mean seed\?\)"),
        ("+cache.dirr=x", r"cache\.dirr is not a known key \(did you mean dir\?\)"),
        ("+layout.ress=4", r"layout\.ress is not a known key \(did you mean res\?\)"),
    ],
)
def test_unknown_keys_are_refused_at_composition(override, match):
    with pytest.raises(ConfigError, match=match):
        compose([override])


def test_cli_validate_refuses_a_typo(capsys):
    from sphri.command import main

    assert main(["validate", "+model.n_estimator=5"]) == 2
    assert "model.n_estimator" in capsys.readouterr().err


@pytest.mark.parametrize(
    "regions, match",
    [
        ("[leg]", r"robot 'reachy' has no region 'leg'; its regions: \['arm', 'torso'\]"),
        ("[arms]", r"no region 'arms' \(did you mean arm\?\)"),
    ],
)
def test_regions_are_checked_against_the_robot(regions, match):
    with pytest.raises(ConfigError, match=match):
        compose([f"data.regions={regions}"])
    compose(["data.regions=[torso]"])


# --------------------------------------------------------------------- meshes
@pytest.mark.parametrize(
    "vertices, faces",
    [
        (np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]]), np.array([[0, 1, 2]])),  # one triangle
        (np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0], [0.1, 0.1, 0]]), np.array([[0, 1, 2], [1, 3, 2]])),  # a sheet
    ],
)
def test_flat_meshes_are_refused_by_name(vertices, faces):
    from sphri.robots.validate import MeshError, make_link

    with pytest.raises(MeshError, match=r"link 'arm' \(tri\.obj\): the mesh is flat"):
        make_link("arm", vertices, faces, source="tri.obj")


# ---------------------------------------------------------------------- cache
def test_unwritable_cache_dir_is_named(tmp_path):
    from sphri.pipeline import open_cache

    a_file = tmp_path / "f"
    a_file.write_text("x")
    for bad in ("/proc/sphri-cache", str(a_file / "cache")):
        with pytest.raises(ConfigError, match=rf"cache\.dir='{bad}' cannot be written"):
            open_cache(compose([f"cache.dir={bad}"]))
    assert open_cache(compose(["cache.dir=/proc/sphri-cache", "cache.enabled=false"])).enabled is False


# ------------------------------------------------------- chance and LOSO folds
def _fold(name: str, classes: list[int]) -> FoldResult:
    cm = np.zeros((len(GESTURES), len(GESTURES)), dtype=np.int64)
    for c in classes:
        cm[c, c] += 3
    return FoldResult(name, 3 * len(classes), 1.0, 1.0, cm, np.ones(len(GESTURES)))


def test_chance_level_counts_the_classes_present():
    from sphri.evaluate.metrics import chance_level

    assert chance_level(CVResult("loso", "rf", [_fold("p1", [0, 6]), _fold("p2", [0, 6])])) == 0.5
    assert chance_level(CVResult("loso", "rf", [_fold("p1", list(range(8)))])) == 0.125


def _windows(participants: list[str]) -> WindowedFrames:
    n = 2 * len(participants)
    geom = TaxelGeometry(
        grid_shape=(1, 2), uv=None, position_m=np.zeros((2, 3)), wrap_v=False, metres_per_u=0.0, metres_per_v=0.0
    )
    return WindowedFrames(
        x=np.zeros((n, 3, 2), np.float32),
        y=np.tile([0, 1], len(participants)),
        groups=np.repeat(participants, 2),
        geometry=geom,
        trial_row=np.arange(n),
        n_dropped=0,
    )


def test_loso_min_participants_refuses_fewer_folds():
    from sphri.evaluate.cv import CVError, LeaveOneSubjectOut

    w = _windows(["participant_01", "participant_02", "participant_03"])
    assert len(LeaveOneSubjectOut(min_participants=3).splits(w)) == 3
    with pytest.raises(CVError, match=r"cv\.min_participants=4: only 3 participants have windows"):
        LeaveOneSubjectOut(min_participants=4).splits(w)
    with pytest.raises(ConfigError, match="cv.min_participants"):
        compose(["cv.min_participants=1"])


def test_missing_participants_are_named_in_the_summary_warnings():
    from types import SimpleNamespace

    from sphri.pipeline import participant_warnings

    cfg = compose(["data.participants=4"])
    trials = pd.DataFrame({"participant": ["participant_01", "participant_02", "participant_03"]})
    dataset = SimpleNamespace(trials=trials, repairs={"participant_without_trials": 1})
    warnings = participant_warnings(cfg, dataset, _windows(["participant_01", "participant_03"]))
    assert any(
        "['participant_02'] have no window with contact" in w and "runs on 2 of 4 participants" in w for w in warnings
    )
    assert any("1 participant(s) without a usable trial" in w for w in warnings)
    assert (
        participant_warnings(
            compose(["data.participants=2"]),
            SimpleNamespace(trials=trials[:2], repairs={}),
            _windows(["participant_01", "participant_02"]),
        )
        == []
    )


def test_summary_shows_chance_from_the_gestures_present(tmp_path):
    from sphri.pipeline import run
    from sphri.tracking.mlflow_tracker import summary_text

    cfg = compose(["+debug=fast", "data.gestures=[hit,tap]", f"output_dir={tmp_path}", "cache.enabled=false"])
    text = summary_text(run(cfg))
    assert "chance 0.500" in text and "chance 0.125" not in text


# --------------------------------------------------- one clean line per error
def _run(args: list[str], tmp_path: Path, env_extra: dict | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(REPO), **(env_extra or {})}
    env.pop("HYDRA_FULL_ERROR", None)
    env.update(env_extra or {})
    return forked_cli.run(["-m", *args], tmp_path, env, 300)


def test_main_entry_point_prints_one_line_for_a_mesh_error_and_the_traceback_on_request(tmp_path):
    tri = tmp_path / "tri.obj"
    tri.write_text("v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 3\n")
    args = [
        "sphri",
        "robot=mesh",
        f"robot.links={{l_arm: {tri}}}",
        "robot.regions={arm: l_arm}",
        "+debug=fast",
        f"output_dir={tmp_path / 'out'}",
        "tracking.enabled=false",
    ]
    res = _run(args, tmp_path)
    assert res.returncode == 1, res.stderr
    assert "Traceback" not in res.stderr and "LinAlgError" not in res.stderr
    errors = [ln for ln in res.stderr.splitlines() if ln.startswith("sphri:")]
    assert len(errors) == 1 and errors[0].startswith("sphri: mesh error: link 'l_arm'") and str(tri) in errors[0]
    verbose = _run([*args, "--verbose"], tmp_path)
    assert verbose.returncode == 1 and "Traceback" in verbose.stderr and "sphri: mesh error" in verbose.stderr
    full = _run(args, tmp_path, {"HYDRA_FULL_ERROR": "1"})
    assert "Traceback" in full.stderr


def test_main_entry_point_data_error_is_one_line(tmp_path):
    res = _run(
        [
            "sphri",
            "data=vr_gesture",
            f"data.root={tmp_path / 'nowhere'}",
            "robot=reachy",
            f"output_dir={tmp_path / 'out'}",
            "tracking.enabled=false",
        ],
        tmp_path,
    )
    # a missing input folder is refused with the config, before any stage (exit 2, the key named)
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert [ln for ln in res.stderr.splitlines() if ln.startswith("sphri:")] == [
        f"sphri: invalid config: data.root='{tmp_path / 'nowhere'}' is invalid: no such folder"
    ]


def test_a_region_the_robot_lacks_is_one_line_naming_it_and_the_robots_regions(tmp_path):
    """A whole-body robot's regions are its body parts and links, known once it is built (``robot=reachy2``
    from its URDF, ``robot=reachy_full``), so the default ``data.regions=[arm]`` passes composition and is
    refused at the data stage: one line naming the region and the robot's regions, exit 2 (it was a
    KeyError's traceback)."""
    res = _run(["sphri", "robot=reachy_full", "+debug=fast", f"output_dir={tmp_path / 'out'}"], tmp_path)
    assert res.returncode == 2 and "Traceback" not in res.stderr, res.stderr[-2000:]
    (line,) = [ln for ln in res.stderr.splitlines() if ln.startswith("sphri:")]
    assert line.startswith("sphri: invalid config: robot 'reachy_full' has no skin region 'arm' (data.regions"), line
    assert "regions: ['base', 'forearm_l'" in line, line  # the message itself, not a KeyError's quoted repr


@pytest.mark.parametrize(
    "verb, argv, kind",
    [
        ("stats", ["data=vr_gesture", "data.root=/nonexistent/ds"], "data error"),
        ("synthesize", ["out=/proc/sphri-ds", "data.participants=2", "+debug=fast"], "invalid config"),
        ("coverage", ["data=vr_gesture", "data.root=/nonexistent/ds", "mlflow=false"], "data error"),
        ("export", ["out=m.sphrimodel", "data=vr_gesture", "data.root=/nonexistent/ds"], "data error"),
        ("skin", ["live", "port=socket://127.0.0.1:9", "model=/nonexistent/m.sphrimodel"], "model file error"),
        ("validate", ["+seeed=3"], "invalid config"),
        ("coverage", ["robot=reachy_full", "+debug=fast", "mlflow=false", "out=cov"], "invalid config"),
    ],
)
def test_every_entry_point_prints_one_line(verb, argv, kind, capsys, tmp_path, monkeypatch):
    from sphri.command import main

    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)
    code = main([verb, *argv])
    err = capsys.readouterr().err
    assert code in (1, 2)
    lines = [ln for ln in err.splitlines() if ln.startswith(("sphri", "Traceback"))]
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(f"sphri {verb}: ") and (kind in lines[0] or verb == "validate"), lines


@pytest.mark.parametrize("study", [[], ["+experiment=scenario_study"]], ids=["coverage", "scenario_study"])
@pytest.mark.parametrize("out", ["taken", "taken/below"])
def test_coverage_out_on_a_file_is_one_line_before_any_computing(study, out, capsys, tmp_path, monkeypatch):
    """``sphri coverage out=PATH`` where PATH (or a folder above it) is a file: one line naming ``out`` and
    the file, exit 2, before the analysis (or the whole-body study) computes anything; it was an
    ``[Errno 17] File exists`` file error after composing."""
    import sphri.pipeline
    import sphri.sessions.study
    from sphri.coverage import main

    def refuse(*_a, **_k):
        raise AssertionError("computing started")

    monkeypatch.setattr(sphri.pipeline, "make_pipeline", refuse)
    monkeypatch.setattr(sphri.sessions.study, "run_study", refuse)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "taken").write_text("a file\n")
    code = main([*study, "+debug=fast", "mlflow=false", f"out={tmp_path / out}"])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err, err
    (line,) = [ln for ln in err.splitlines() if ln.startswith("sphri")]
    assert f"out={tmp_path / out} is invalid: {tmp_path / 'taken'} is a file, not a folder" in line, line
    assert (tmp_path / "taken").read_text() == "a file\n"


@pytest.mark.parametrize(
    "verb, argv, named",
    [
        ("synthesize", ["out=taken"], "taken is a file, not a folder"),
        ("synthesize", ["out=taken/ds"], "taken is a file, not a folder"),
        ("synthesize", ["out=taken/sessions", "what=sessions"], "taken is a file, not a folder"),
        ("export", ["out=folder"], "folder is a folder; give a file name (e.g. folder/model.sphrimodel)"),
        ("export", ["out=taken/m.sphrimodel"], "taken is a file, not a folder"),
    ],
)
def test_an_output_path_in_the_way_is_one_line_before_any_computing(verb, argv, named, capsys, tmp_path, monkeypatch):
    """``sphri synthesize`` / ``sphri export`` with ``out=`` on a file (or a folder where a file is written):
    one line naming ``out``, exit 2, before generating or training; they failed after the work was done
    (``[Errno 20] Not a directory``, ``[Errno 21] Is a directory``), the trained model lost."""
    import sphri.data.synthetic
    import sphri.pipeline
    import sphri.sessions.synthetic
    from sphri.command import main

    def refuse(*_a, **_k):
        raise AssertionError("computing started")

    monkeypatch.setattr(sphri.pipeline, "make_pipeline", refuse)
    monkeypatch.setattr(sphri.data.synthetic.SyntheticData, "load", refuse)
    monkeypatch.setattr(sphri.sessions.synthetic.SyntheticSessions, "load", refuse)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "taken").write_text("a file\n")
    (tmp_path / "folder").mkdir()
    code = main([verb, *argv, "+debug=fast"])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err, err
    (line,) = [ln for ln in err.splitlines() if ln.startswith("sphri")]
    assert f"invalid config: {argv[0]} is invalid: {named}" in line, line
    assert (tmp_path / "taken").read_text() == "a file\n" and not list((tmp_path / "folder").iterdir())


@pytest.mark.parametrize(
    "verb, argv, code, line",
    [
        ("export", ["out=folder", "+debug=fast"], 2, "sphri export: invalid config: out=folder is invalid: "),
        ("skin", ["record", "port=loop://", "out=taken/rec.npz"], 1, "sphri skin: recording error: out=taken/rec.npz"),
    ],
)
def test_a_verbs_runtime_error_names_the_verb_as_its_usage_errors_do(
    verb, argv, code, line, tmp_path, capsys, monkeypatch
):
    """``sphri export``/``sphri skin`` (dispatched by ``sphri.command.call``): an error past the argument
    check was prefixed with the module (``sphri.export.train:``, ``sphri.hardware.skin:``) while a bad
    argument of the same command said ``sphri export:``."""
    from sphri.command import BY_NAME, call

    monkeypatch.chdir(tmp_path)
    (tmp_path / "folder").mkdir()
    (tmp_path / "taken").write_text("a file\n")
    assert call(BY_NAME[verb], argv) == code
    (got,) = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("sphri")]
    assert got.startswith(line), got


def test_a_layout_file_that_does_not_read_is_one_line_naming_it(tmp_path):
    """``layout=file layout.path=F`` where F is not an iCub calibration text (no ``[calibration]`` rows):
    the job printed a ValueError's traceback from the layout stage; now ``layout file error: F: ...``, exit 1."""
    bad = tmp_path / "taxels.csv"
    bad.write_text("x,y,z\n0,0,0\n")
    args = ["sphri", "+debug=fast", "layout=file", "encoder=coverage", f"layout.path={bad}"]
    res = _run([*args, f"output_dir={tmp_path / 'out'}", "tracking.enabled=false"], tmp_path)
    assert res.returncode == 1 and "Traceback" not in res.stderr, res.stderr[-2000:]
    (line,) = [ln for ln in res.stderr.splitlines() if ln.startswith("sphri:")]
    assert line == f"sphri: layout file error: {bad}: no '[calibration]' rows (x y z nx ny nz) found", line
