"""The sweep report end to end, on fake sweeps logged through the real MLflow tracker."""

from __future__ import annotations

import base64
import json
from html.parser import HTMLParser

import numpy as np
import pandas as pd
import pytest
from fake_sweep import grid_resolution, make_sweep
from markupsafe import escape  # the page's autoescape (' as &#39;)

from sphri.command import main as sphri_main
from sphri.report import RuleSettings, load_sweep, make_report
from sphri.report.saturation import certified_saturation, points_text
from sphri.report.sweep import ReportError, group_keys


def main(argv: list[str]) -> int:
    """``sphri report ARGV``."""
    return sphri_main(["report", *argv])


PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
RULE = RuleSettings(n_boot=400, seed=0)
PNG_ONLY = ("png",)  # PDF and SVG of every report figure: tests/report/test_report_figures.py


class _Page(HTMLParser):
    def __init__(self):
        super().__init__()
        self.imgs: list[str] = []
        self.tags: set[str] = set()
        self.urls: list[str] = []
        self.tables: list[list[list[str]]] = []
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        self.tags.add(tag)
        if tag == "table":
            self.tables.append([])
        elif tag == "tr" and self.tables:
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self._cell = []
        a = dict(attrs)
        if tag == "img":
            self.imgs.append(a.get("src", ""))
        for k in ("href", "src"):
            if a.get(k) and not a[k].startswith("data:"):
                self.urls.append(a[k])

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self.tables[-1][-1].append("".join(self._cell).strip())
            self._cell = None


@pytest.fixture(scope="module")
def built(two_model_sweep):
    report, files, text = make_report(two_model_sweep.sweep_dir, rule=RULE, formats=PNG_ONLY)
    return two_model_sweep, report, files, text


def test_load_sweep_groups_by_model_and_reads_participants(two_model_sweep):
    sw = load_sweep(two_model_sweep.sweep_dir)
    assert sw.group_keys == ["model"], "model varies; model.n_estimators/model.hidden follow from it"
    assert sorted(sw.runs["group"].unique()) == ["cnn_gru", "rf"]
    assert len(sw.runs) == 15 and len(sw.failed) == 1
    assert sw.failed[0]["res"] == "36" and "boom" in sw.failed[0]["error"]
    assert sw.synthetic == "all"
    assert set(sw.folds["participant"]) == set(two_model_sweep.participants)
    assert {f"recall_{g}" for g in ("hit", "poke", "grab")} <= set(sw.folds.columns)
    rf = sw.runs[sw.runs["group"] == "rf"].sort_values("res")
    assert rf["pitch_u_mm"].to_numpy() == pytest.approx([grid_resolution(r)["pitch_u_mm"] for r in rf["res"]], rel=1e-5)
    # the same sweep by parent run id and tracking URI
    by_id = load_sweep(two_model_sweep.parent_id, uri=two_model_sweep.uri)
    assert set(by_id.runs["run_id"]) == set(sw.runs["run_id"]) and by_id.sweep_dir == sw.sweep_dir


def test_saturation_numbers_match_the_logged_scores(built):
    truth, report, files, text = built
    rf = next(g for g in report.groups if g.label == "rf")
    # recompute from the generated per-participant accuracies, without MLflow in between
    expected, cert = certified_saturation(truth.accuracy["rf"], "0.01", n_boot=RULE.n_boot, seed=RULE.seed)
    assert rf.sat.index == expected.index and rf.sat.interval == expected.interval
    assert rf.accuracy == pytest.approx(truth.accuracy["rf"], abs=1e-6)
    res = truth.res[expected.index]
    r = grid_resolution(res)
    pitch = max(r["pitch_u_mm"], r["pitch_v_mm"])
    lo_res, hi_res = truth.res[expected.interval[0]], truth.res[expected.interval[1]]
    pitches = [max(grid_resolution(x)["pitch_u_mm"], grid_resolution(x)["pitch_v_mm"]) for x in (hi_res, lo_res)]
    # the sentence never states the point alone: the interval is in it, and the tolerance it uses
    assert (
        f"A taxel pitch of at most {pitch:.1f} mm (95% interval {min(pitches):.1f} to {max(pitches):.1f} mm; "
        f"{r['area_per_taxel_cm2']:.2f} cm^2 per taxel) keeps accuracy within {points_text(cert.tolerance_used)}"
    ) in rf.requirement
    assert "of the best at every finer swept pitch, with 95% confidence, paired over participants" in rf.requirement
    # the sentence never states a tolerance smaller than the one the study certifies
    assert expected.tolerance == cert.tolerance_used == max(0.01, cert.certifiable)
    assert cert.raised == ("the 1 point of accuracy (0.01) asked for cannot be" in rf.requirement)
    # one seed: the rerun noise is estimated from the jitter between neighbouring resolutions, and stated
    assert cert.noise.source == "neighbours"
    assert f"rerun noise {cert.noise.per_participant:.3f} per participant" in text
    assert f"smallest certifiable tolerance {points_text(cert.certifiable)}" in text
    assert rf.pitch_interval_mm == pytest.approx(sorted(pitches), rel=1e-5)  # params keep 6 digits
    assert f"{min(pitches):.1f} to {max(pitches):.1f} mm pitch" in rf.interval_text
    # mean +/- std over participants, as the study's figure
    m = truth.accuracy["rf"].mean(0)
    assert rf.points["accuracy_mean"].to_numpy() == pytest.approx(m, abs=1e-6)
    assert rf.points["accuracy_std"].to_numpy() == pytest.approx(truth.accuracy["rf"].std(0, ddof=1), abs=1e-6)
    saved = json.loads(files.tables["json"].read_text())
    row = next(g for g in saved["groups"] if g["group"] == "rf")
    assert row["saturation_res"] == res and row["saturation_pitch_mm"] == pytest.approx(pitch, rel=1e-5)
    assert row["pitch_low_mm"] == pytest.approx(min(pitches), rel=1e-5) and row["interval_index"] == list(
        expected.interval
    )
    assert isinstance(row["tolerance"], float) and isinstance(row["synthetic"], bool)


def test_html_is_self_contained_with_figures_sentence_and_synthetic_label(built):
    truth, report, files, text = built
    page = files.html.read_text(encoding="utf-8")
    parser = _Page()
    parser.feed(page)
    assert not parser.urls, f"external resources: {parser.urls}"
    assert "script" not in parser.tags and "link" not in parser.tags
    assert len(parser.imgs) >= 5, "curves, bootstrap, recall and two confusion matrices"
    for src in parser.imgs:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == PNG_MAGIC
    assert "SYNTHETIC DATA" in page
    for g in report.groups:
        assert escape(g.requirement) in page
    assert "A taxel pitch of at most" in page and "bootstrap interval over 8 participants" in page
    assert page.count('class="req"') == 2
    assert "FAILED job" in page and "boom at res 36" in page
    # the comparison table: one row per model, with the saturation pitch of each
    comp = next(t for t in parser.tables if t[0][0] == "model")
    head = comp[0]
    rows = {r[0]: dict(zip(head, r)) for r in comp[1:]}
    assert sorted(rows) == ["cnn_gru", "rf"]
    for g in report.groups:
        assert rows[g.label]["saturation pitch (mm)"] == f"{g.recommended['pitch_mm']:.1f}"
        assert rows[g.label]["participants"] == "8"


def test_files_text_and_mlflow_parent(built):
    from mlflow.tracking import MlflowClient

    truth, report, files, text = built
    assert files.out_dir == truth.sweep_dir / "report"
    for name in (
        "report.html",
        "summary.txt",
        "accuracy_vs_resolution.png",
        "recall_vs_resolution.png",
        "saturation_bootstrap.png",
        "confusion_rf.png",
        "confusion_cnn_gru.png",
        "saturation.csv",
        "points.csv",
        "saturation.json",
    ):
        assert (files.out_dir / name).is_file(), name
    assert (files.out_dir / "accuracy_vs_resolution.png").read_bytes()[:8] == PNG_MAGIC
    assert text.startswith("sphri skin resolution report")
    assert "SYNTHETIC DATA" in text and "A taxel pitch of at most" in text
    assert "gestures, finest need first:" in text
    assert (files.out_dir / "summary.txt").read_text().strip() == text.strip()
    client = MlflowClient(truth.uri)
    parent = client.get_run(truth.parent_id)
    assert parent.data.tags["mlflow.note.content"].startswith("sphri skin resolution report")
    assert parent.data.tags["sphri.synthetic"] == "true"
    assert parent.data.tags["sphri.sweep_note"].startswith("sweep: layout.res=")
    assert "A taxel pitch of at most" in parent.data.tags["sphri.report.requirement"]
    logged = {a.path for a in client.list_artifacts(truth.parent_id, "report")}
    assert {"report/report.html", "report/accuracy_vs_resolution.png", "report/summary.txt"} <= logged
    rf = next(g for g in report.groups if g.label == "rf")
    assert parent.data.metrics["saturation/rf/saturation_pitch_mm"] == pytest.approx(rf.recommended["pitch_mm"])


def test_per_gesture_recall_finds_the_gestures_that_need_fine_skin(built):
    _, report, _, _ = built
    rf = next(g for g in report.groups if g.label == "rf")
    # the fake folds give poke the slowest-rising recall
    order = {g: rf.gesture_sat[g].index for g in rf.gesture_sat}
    assert order["poke"] >= np.median(list(order.values()))
    assert set(rf.gesture_sat) == {"hit", "pat", "poke", "push", "rub", "stroke", "tap", "grab"}


def test_morphology_sweep_compares_robots_and_real_data_is_not_labelled_synthetic(store, tmp_path):
    truth = make_sweep(
        store, tmp_path / "morph", [2, 6, 18], robots=["reachy", "nao_child"], synthetic=False, n_participants=4
    )
    report, files, text = make_report(truth.sweep_dir, rule=RULE, log_to_mlflow=False, formats=PNG_ONLY)
    assert report.sweep.group_keys == ["robot"]
    assert [g.label for g in report.groups] == ["nao_child", "reachy"]
    comp = pd.read_csv(files.tables["comparison"])
    assert sorted(comp["robot"]) == ["nao_child", "reachy"] and "saturation_pitch_mm" in comp.columns
    page = files.html.read_text()
    assert "SYNTHETIC" not in page and "SYNTHETIC" not in text
    assert "only 4 participants" in page


def test_one_participant_sweep_reports_no_interval_with_a_note(store, tmp_path):
    truth = make_sweep(store, tmp_path / "one", [1, 4, 12], n_participants=1)
    report, files, text = make_report(
        truth.sweep_dir, rule=RULE, out_dir=tmp_path / "rep", log_to_mlflow=False, formats=PNG_ONLY
    )
    g = report.groups[0]
    assert g.sat.interval is None and g.pitch_interval_mm is None
    assert "No bootstrap interval: only one participant" in g.interval_text
    assert "only one participant" in files.html.read_text()
    assert "A taxel pitch of at most" in text


def test_without_artifacts_scores_come_from_participant_metrics(store, tmp_path):
    truth = make_sweep(store, tmp_path / "noart", [1, 3, 9], artifacts=False, n_participants=3)
    report, files, text = make_report(truth.sweep_dir, rule=RULE, log_to_mlflow=False, formats=PNG_ONLY)
    g = report.groups[0]
    assert g.accuracy == pytest.approx(truth.accuracy["rf"], abs=1e-6)
    assert np.isnan(g.macro_f1).all() and not g.gesture_sat
    assert any("no confusion.png" in n for n in report.notes)
    assert "No confusion matrix artifact" in files.html.read_text()


def test_resumed_sweep_finds_jobs_through_status_files(store, tmp_path, two_model_sweep):
    """A re-run sweep whose jobs were skipped points at runs of an earlier parent."""
    from sphri.tracking.mlflow_tracker import PARENT_FILE, MlflowTracker

    tracker = MlflowTracker()
    new_dir = tmp_path / "resumed"
    new_dir.mkdir()
    pid = tracker.start_parent(str(two_model_sweep.output_dir), str(new_dir), "resumed", ["layout.res=1,2"])
    (new_dir / PARENT_FILE).write_text(json.dumps({"run_id": pid, "sweep_id": "resumed", "uri": two_model_sweep.uri}))
    old = load_sweep(two_model_sweep.sweep_dir).runs
    for i, rid in enumerate(old[old["group"] == "rf"]["run_id"][:3]):
        (new_dir / str(i)).mkdir()
        (new_dir / str(i) / "sphri_status.json").write_text(
            json.dumps({"job": i, "status": "SKIPPED", "mlflow_run_id": rid})
        )
    sw = load_sweep(new_dir)
    assert len(sw.runs) == 3 and set(sw.runs["run_id"]) <= set(old["run_id"])


def test_cli_prints_the_summary_and_fails_clearly(two_model_sweep, tmp_path, capsys):
    assert (
        main(
            [
                str(two_model_sweep.sweep_dir),
                "--n-boot",
                "100",
                "--no-log",
                "--out",
                str(tmp_path / "r"),
                "--formats",
                "png",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "A taxel pitch of at most" in out and str(tmp_path / "r" / "report.html") in out
    assert main([str(tmp_path)]) == 2
    assert "mlflow_parent_run.json" in capsys.readouterr().err
    assert main(["not-a-run"]) == 2
    assert "neither a sweep directory" in capsys.readouterr().err
    assert main([str(tmp_path), "--ci", "2"]) == 2  # one line naming the key (sphri.args)


def test_group_keys_keep_only_settings_not_fixed_by_components():
    params = [
        {"model": "rf", "model.n_estimators": "100", "robot": "reachy", "layout.res": "1", "resolution.n_taxels": "1"},
        {"model": "cnn_gru", "model.hidden": "32", "robot": "reachy", "layout.res": "2", "resolution.n_taxels": "4"},
        {"model": "rf", "model.n_estimators": "300", "robot": "reachy", "layout.res": "1", "resolution.n_taxels": "1"},
    ]
    assert group_keys(params) == ["model", "model.n_estimators"]
    assert group_keys(params[:2]) == ["model"]
    # assumption variants: what a variant fixes (its encoder, its noise.p) is not a key of its own
    variants = [
        {"variant": v, "encoder": e, "noise.p": p, "model": "rf", "layout.res": str(r)}
        for v, e, p in (
            ("reference", "ellipse", "0.02"),
            ("coverage", "coverage", "0.02"),
            ("noise0", "ellipse", "0.0"),
        )
        for r in (1, 2)
    ]
    assert group_keys(variants) == ["variant"]
    assert group_keys([{**p, "model": m} for p in variants for m in ("rf", "cnn_gru")]) == ["variant", "model"]
    with pytest.raises(ReportError, match="neither"):
        load_sweep("nope")


def test_one_resolution_per_group_is_a_comparison_without_saturation(store, tmp_path):
    """A noise or layout comparison at a fixed resolution: a table, no curve to saturate."""
    truth = make_sweep(store, tmp_path / "fixed", [18], models=["rf", "cnn_gru"], n_participants=3)
    report, files, text = make_report(truth.sweep_dir, rule=RULE, log_to_mlflow=False, formats=PNG_ONLY)
    assert len(report.groups) == 2
    for g in report.groups:
        assert g.requirement.startswith("One resolution only (layout.res=18")
        assert "A taxel pitch of at most" not in g.requirement
    assert "bootstrap" not in files.figures
    assert len(pd.read_csv(files.tables["comparison"])) == 2


@pytest.mark.slow
def test_real_sweep_end_to_end(sweep_then_report):
    """A real (tiny) multirun of the pipeline, then ``python -m sphri report`` on its directory."""
    sweep, rep = sweep_then_report(["+debug=fast", "layout.res=1,3,6"], 3, ["--n-boot", "200"], timeout=900)
    assert "A taxel pitch of at most" in rep.stdout and "SYNTHETIC" in rep.stdout
    parser = _Page()
    parser.feed((sweep / "report" / "report.html").read_text())
    assert len(parser.imgs) >= 3 and not parser.urls


def test_tolerance_table_in_html_csv_and_text(built):
    truth, report, files, text = built
    tol = pd.read_csv(files.tables["tolerances"])
    assert sorted(tol["tolerance"].astype(str).unique()) == ["0.01", "0.02", "0.03"]
    assert len(tol) == 3 * len(report.groups)
    assert tol.groupby("group")["used_in_sentence"].sum().eq(1).all(), "one tolerance per curve is the sentence's"
    assert set(tol[tol["used_in_sentence"]]["tolerance"].astype(str)) == {"0.01"}
    for g in report.groups:
        for t in g.by_tolerance:
            expected, _ = certified_saturation(g.accuracy, t.tolerance, n_boot=RULE.n_boot, seed=RULE.seed)
            assert t.sat.index == expected.index and t.sat.interval == expected.interval
            row = tol[(tol["group"] == g.label) & (tol["tolerance"].astype(str) == t.tolerance.name)].iloc[0]
            assert row["saturation_res"] == truth.res[expected.index]
    # a looser tolerance never asks for a finer skin
    rf = next(g for g in report.groups if g.label == "rf")
    idx = {t.tolerance.name: t.sat.index for t in rf.by_tolerance}
    assert idx["0.03"] <= idx["0.02"] <= idx["0.01"]
    page = files.html.read_text()
    assert "Requirement under several tolerances" in page and "3 points of accuracy (0.03)" in page
    assert "The requirement sentence asks for 1 point of accuracy (0.01)" in page
    assert "tolerance 3 points of accuracy (0.03):" in text and "<- used in the sentence" in text
    assert not report.sensitivity and "tornado" not in files.figures, "no variants, no sensitivity section"


@pytest.mark.parametrize("spelling", ["flags", "key=value"])
def test_cli_tolerance_options(two_model_sweep, tmp_path, capsys, spelling):
    """The report's options in argparse flags and in ``key=value`` words, like every sphri command."""
    out = tmp_path / "r"
    if spelling == "flags":
        args = ["--n-boot", "50", "--no-log", "--out", str(out), "--tolerances", "0.05,0.04", "--tolerance", "0.03"]
        args += ["--formats", "png"]
    else:
        args = ["n_boot=50", "mlflow=false", f"out={out}", "formats=png", "tolerances=0.05,0.04", "tolerance=0.03"]
    assert main([str(two_model_sweep.sweep_dir), *args]) == 0
    tol = pd.read_csv(out / "tolerances.csv")
    assert sorted(tol["tolerance"].astype(str).unique()) == ["0.03", "0.04", "0.05"]
    assert "within 3 points of accuracy (0.03) of the best" in capsys.readouterr().out
    assert main([str(two_model_sweep.sweep_dir), "--tolerances", "lots"]) == 2


@pytest.mark.parametrize(
    "args, match",
    [
        (["n_boots=50"], "unknown argument 'n_boots' (did you mean n_boot?)"),
        (["mlflow=maybe"], "mlflow=maybe is invalid"),
    ],
)
def test_cli_refuses_bad_arguments(two_model_sweep, capsys, args, match):
    assert main([str(two_model_sweep.sweep_dir), *args]) == 2
    assert match in capsys.readouterr().err


def test_cli_formats_are_checked(two_model_sweep, tmp_path, capsys):
    assert main([str(two_model_sweep.sweep_dir), "formats=pdf,svg"]) == 2  # names the value and the rule
    err = capsys.readouterr().err
    assert "formats=pdf,svg is invalid" in err and "png included" in err, err
    with pytest.raises(ValueError, match="formats=png,tiff is invalid"):
        make_report(two_model_sweep.sweep_dir, formats=("png", "tiff"))
    assert (
        main([str(two_model_sweep.sweep_dir), "n_boot=50", "mlflow=false", f"out={tmp_path / 'png'}", "formats=png"])
        == 0
    )
    assert {p.suffix for p in (tmp_path / "png").glob("*_vs_resolution.*")} == {".png"}


def test_sensitivity_sweep_reports_the_requirement_per_assumption(store, tmp_path):
    """Variants with known curves: noise0 saturates coarser (tau 1.5), noise5 finer (tau 8) than the reference (3)."""
    variants = {"reference": (3.0, 0.02), "noise0": (1.5, 0.0), "noise5": (8.0, 0.05)}
    truth = make_sweep(
        store, tmp_path / "sens", [1, 2, 3, 4, 6, 9, 13, 18, 27, 36, 50], variants=variants, n_participants=10, seed=3
    )
    report, files, text = make_report(truth.sweep_dir, rule=RULE, log_to_mlflow=False, formats=PNG_ONLY)
    assert report.sweep.group_keys == ["variant"], "noise.p is fixed by the variant: not a key of its own"
    assert sorted(g.label for g in report.groups) == ["noise0", "noise5", "reference"]
    (sens,) = report.sensitivity
    assert sens.label == "" and sens.reference is not None and sens.reference.label == "reference"
    pitch = {g.label: float(g.recommended["pitch_mm"]) for g in report.groups}
    assert pitch["noise0"] >= pitch["reference"] >= pitch["noise5"]
    ref = sens.reference
    lo, hi = ref.pitch_interval_mm
    assert sens.sentence.startswith(
        f"A taxel pitch of at most {pitch['reference']:.1f} mm (95% interval {lo:.1f} to "
        f"{hi:.1f} mm) under the reference assumptions; between"
    )
    assert (
        f"between {min(pitch.values()):.1f} mm" in sens.sentence
        and f"and {max(pitch.values()):.1f} mm" in sens.sentence
    )
    assert "across the 3 assumptions tested" in sens.sentence
    table = pd.read_csv(files.tables["sensitivity"])
    assert sorted(table["variant"]) == ["noise0", "noise5", "reference"]
    assert table.set_index("variant").loc["reference", "shift_from_reference_mm"] == 0
    assert "sensitivity_tornado.png" in {p.name for p in files.figures.values()}
    assert (files.out_dir / "sensitivity_tornado.png").read_bytes()[:8] == PNG_MAGIC
    page = files.html.read_text()
    assert escape(sens.sentence) in page and "Sensitivity to the assumptions" in page
    assert sens.sentence in text
    saved = json.loads(files.tables["json"].read_text())
    assert saved["sensitivity"][0]["sentence"] == sens.sentence


def test_html_escapes_group_names_taken_from_the_sweep(store, tmp_path):
    """A swept value is printed as text: a model named like a script tag must not become markup."""
    hostile = "<script>alert('x')</script>"
    truth = make_sweep(store, tmp_path / "hostile", [1, 3, 9], models=["rf", hostile], n_participants=3)
    report, files, _ = make_report(truth.sweep_dir, rule=RULE, log_to_mlflow=False, formats=PNG_ONLY)
    assert hostile in {g.label for g in report.groups}
    page = files.html.read_text()
    assert "<script" not in page.lower()
    parser = _Page()
    parser.feed(page)
    assert "script" not in parser.tags
    # the label survives as text in the comparison, per-gesture and per-resolution tables
    assert sum(hostile in cell for table in parser.tables for row in table for cell in row) >= 2
    assert page.count("&lt;script&gt;alert(") >= 4


@pytest.mark.parametrize("out", ["taken", "taken/report"])
def test_cli_out_on_a_file_is_one_line_before_reading_the_sweep(tmp_path, capsys, monkeypatch, out):
    """``sphri report DIR out=PATH`` where PATH (or a folder above it) is a file: one line naming ``out``,
    exit 2, before the sweep is read (it was ``file error: [Errno 17] File exists`` after the report's work)."""
    import sphri.report.command as report_command

    def refuse(*_a, **_k):
        raise AssertionError("the sweep was read")

    monkeypatch.setattr(report_command, "make_report", refuse)
    (tmp_path / "taken").write_text("a file\n")
    assert main([str(tmp_path), f"out={tmp_path / out}"]) == 2
    (line,) = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert line.startswith("sphri") and line.endswith(
        f": out={tmp_path / out} is invalid: {tmp_path / 'taken'} is a file, not a folder"
    ), line


def test_cli_out_holding_other_files_is_refused_before_reading_the_sweep(tmp_path, capsys, monkeypatch):
    """``sphri report DIR out=FOLDER`` logs the whole folder to MLflow: a folder holding other files (not an earlier
    report) would be uploaded with it, so it is refused in one line before the sweep is read; an earlier report's
    folder is written again."""
    import sphri.report.command as report_command

    calls = []

    def record(*_a, **kw):
        calls.append(kw["out_dir"])
        raise ValueError("stop here")

    monkeypatch.setattr(report_command, "make_report", record)
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("not a report\n")
    assert main([str(tmp_path), f"out={out}"]) == 2
    (line,) = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert line.endswith(
        f"out={out} is invalid: {out} holds files and no earlier report (report.html); the report "
        "is logged to MLflow as the whole folder: give a new or empty folder"
    ), line
    assert not calls and [p.name for p in out.iterdir()] == ["thesis.tex"]
    (out / "report.html").write_text("<html></html>")  # an earlier report's folder: written again
    main([str(tmp_path), f"out={out}"])
    assert calls == [str(out)]


def test_command_line_names_each_key_once_with_the_command_lines_value(store, tmp_path):
    # the parent's note holds an experiment's sweeper params, then the command line's overrides
    from mlflow.tracking import MlflowClient

    truth = make_sweep(store, tmp_path / "dup", [1, 3], n_participants=3)
    note = "sweep: model=rf,cnn_gru layout.res=1,3 +experiment=resolution_sweep model=rf tracking.log_model=false"
    MlflowClient(truth.uri).set_tag(truth.parent_id, "mlflow.note.content", note)
    _, files, text = make_report(truth.sweep_dir, rule=RULE, log_to_mlflow=False, formats=PNG_ONLY)
    line = "command: python -m sphri -m model=rf layout.res=1,3 +experiment=resolution_sweep tracking.log_model=false"
    assert line in text.splitlines()
    assert escape(line) in files.html.read_text()


def test_sweep_command_keeps_each_keys_first_place_and_last_value_as_hydra_does():
    from sphri.report.render import sweep_command

    assert sweep_command("sweep: a=1 b='x y' c=[1, 2] a=2 ~d c=[3]") == "a=2 b='x y' c=[3] ~d"
    assert sweep_command("sweep: +e=x e=y") == "+e=x e=y", "adding a key (+e) and setting it (e) are two overrides"
    assert sweep_command("sweep: layout.res=1,2") == "layout.res=1,2"
    assert sweep_command("done in 3 s") is None
