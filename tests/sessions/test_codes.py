"""Gestures coded by hand (sphri.sessions.codes): the codes replace the model's labels, Cohen's kappa per pair of
coders, and every defect of the file is one line naming the file, the row and the field."""

from __future__ import annotations

import csv
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from sphri.config import ConfigError
from sphri.sessions.codes import SHEET_COLUMNS, CodesError, read_codes
from sphri.types import GESTURES

#: The model's labels of six episodes (one per session); what ana and ben coded.
MODEL = ["push", "push", "rub", "tap", "hit", "push"]
ANA = ["push", "pat", "rub", "tap", "hit", "grab"]
BEN = ["push", "pat", "stroke", "tap", "hit"]  # ben left the last episode out


def _study():
    """Six coded episodes of six sessions (session k starts at global frame 100 k) and their model labels."""
    n = len(MODEL)
    coded = pd.DataFrame(
        {
            "session": np.arange(n),
            "participant": [f"participant_{1 + k // 3:02d}" for k in range(n)],
            "scenario": [f"S{1 + k % 3}" for k in range(n)],
            "repetition": 1,
            "episode": [1, 1, 2, 1, 1, 3],
            "start_frame": 100 * np.arange(n) + 10,
            "end_frame": 100 * np.arange(n) + 40,
            "dominant_part": "torso_top",
            "gesture": MODEL,
            "confidence": 0.4,
        }
    )
    for g in GESTURES:
        coded[f"p_{g}"] = np.where(coded["gesture"] == g, 0.4, 0.6 / (len(GESTURES) - 1))
    ds = SimpleNamespace(sessions=pd.DataFrame({"start": 100 * np.arange(n)}))
    return coded, ds


def _rows(coder: str, gestures: list[str]) -> list[dict]:
    coded, _ = _study()
    out = []
    for k, g in enumerate(gestures):
        e = coded.iloc[k]
        out.append(
            dict.fromkeys(SHEET_COLUMNS, "")
            | dict(
                episode_id=f"{e.participant}/{e.scenario}/r1/e{e.episode}",
                start_frame=10,
                end_frame=40,
                suggestion=e.gesture,
                gesture=g,
                coder=coder,
            )
        )
    return out


def _write(path: Path, rows: list[dict], columns=SHEET_COLUMNS) -> Path:
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(columns), extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    return path


def _kappa_by_hand(a: list[str], b: list[str]) -> float:
    """Cohen's kappa from its definition: (p_o - p_e) / (1 - p_e), p_e from each coder's own marginals."""
    n = len(a)
    po = sum(x == y for x, y in zip(a, b)) / n
    pe = sum((a.count(g) / n) * (b.count(g) / n) for g in set(a) | set(b))
    return (po - pe) / (1 - pe)


def test_the_study_coders_codes_replace_the_labels_and_kappa_is_cohens(tmp_path):
    coded, ds = _study()
    path = _write(tmp_path / "codes.csv", _rows("ana", ANA) + _rows("ben", BEN))
    codes = read_codes(path, coded, ds)
    assert codes.coder == "ana" and codes.coders == ["ana", "ben"]
    out = codes.apply(coded)
    assert out["gesture"].tolist() == ANA and out["suggestion"].tolist() == MODEL
    assert (out["coder"] == "ana").all() and np.allclose(out["suggestion_confidence"], 0.4)
    p = out[[f"p_{g}" for g in GESTURES]].to_numpy()
    assert np.array_equal(p.argmax(axis=1), [GESTURES.index(g) for g in ANA]) and np.allclose(p.sum(axis=1), 1)
    assert coded["gesture"].tolist() == MODEL  # the model's labels are left alone
    rows = {(r["coder_a"], r["coder_b"]): r for r in codes.summary(out)["agreement"]}
    pair = rows["ana", "ben"]  # over the five episodes both coded
    assert pair["n_episodes"] == 5 and pair["agreement"] == pytest.approx(4 / 5)
    assert pair["kappa"] == pytest.approx(_kappa_by_hand(ANA[:5], BEN))
    model = rows["ana", "model"]
    assert model["n_episodes"] == 6 and model["kappa"] == pytest.approx(_kappa_by_hand(ANA, MODEL))
    notes = codes.notes(out)
    assert any("coder 'ana' and coder 'ben' agree on 4 of 5 episodes" in n and "kappa" in n for n in notes), notes


def test_the_study_coder_can_be_named_and_must_have_coded_every_episode(tmp_path):
    coded, ds = _study()
    path = _write(tmp_path / "codes.csv", _rows("ben", BEN) + _rows("ana", ANA))
    with pytest.raises(
        CodesError, match=r"'ben', whose codes the study uses, has no row for 1 of the 6 .*participant_02/S3/r1/e3"
    ):
        read_codes(path, coded, ds)  # ben's row comes first: ben is the study's coder by default
    assert read_codes(path, coded, ds, coder="ana").apply(coded)["gesture"].tolist() == ANA
    with pytest.raises(CodesError, match=r"coder='cleo': no row .* coded by them; coders: ben, ana"):
        read_codes(path, coded, ds, coder="cleo")


def test_gesture_cells_are_read_as_written_by_people(tmp_path):
    coded, ds = _study()
    rows = _rows("ana", ANA)
    rows[0]["gesture"], rows[1]["gesture"] = " Push", "PAT "
    out = read_codes(_write(tmp_path / "codes.csv", rows), coded, ds).apply(coded)
    assert out["gesture"].tolist() == ANA


def test_kappa_is_undefined_when_both_coders_used_one_and_the_same_gesture(tmp_path):
    coded, ds = _study()
    same = ["push"] * 6
    codes = read_codes(_write(tmp_path / "codes.csv", _rows("ana", same) + _rows("ben", same)), coded, ds)
    out = codes.apply(coded)
    pair = codes.summary(out)["agreement"][0]
    assert pair["agreement"] == 1.0 and pair["kappa"] is None  # NaN in summary.json would not be strict JSON
    assert any("kappa undefined" in n for n in codes.notes(out))


def _broken(kind: str) -> tuple[list[dict], tuple]:
    rows = _rows("ana", ANA)
    if kind == "unknown gesture":
        rows[1]["gesture"] = "patt"
        return rows, ("row 3", "'gesture'", "'patt'", "did you mean pat?")
    if kind == "empty gesture":
        rows[2]["gesture"] = ""
        return rows, ("row 4", "'gesture' is empty", "participant_01/S3/r1/e2")
    if kind == "empty coder":
        rows[5]["coder"] = " "
        return rows, ("row 7", "'coder' is empty")
    if kind == "unknown episode":
        rows[0]["episode_id"] = "participant_09/S1/r1/e1"
        return rows, ("row 2", "'episode_id'", "participant_09/S1/r1/e1", "not an episode this study codes")
    if kind == "other frames":
        rows[3]["start_frame"] = 12
        return rows, ("row 5", "'start_frame' is 12", "start_frame=10")
    if kind == "frame not a number":
        rows[4]["end_frame"] = "forty"
        return rows, ("row 6", "'end_frame'", "'forty'", "not a frame number")
    if kind == "coded twice":
        rows.append(dict(rows[0], gesture="hit"))
        return rows, ("row 8", "'coder'", "'ana' codes episode participant_01/S1/r1/e1 a second time", "row 2")
    if kind == "empty episode id":
        rows[1]["episode_id"] = ""
        return rows, ("row 3", "'episode_id' is empty")
    raise AssertionError(kind)


@pytest.mark.parametrize(
    "kind",
    [
        "unknown gesture",
        "empty gesture",
        "empty coder",
        "unknown episode",
        "other frames",
        "frame not a number",
        "coded twice",
        "empty episode id",
    ],
)
def test_each_bad_row_is_one_line_naming_file_row_and_field(tmp_path, kind):
    coded, ds = _study()
    rows, words = _broken(kind)
    path = _write(tmp_path / "codes.csv", rows)
    with pytest.raises(CodesError) as err:
        read_codes(path, coded, ds)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(str(path)) and all(w in msg for w in words), msg
    assert isinstance(err.value, ConfigError)  # the study's one-line errors: exit 2


def test_bad_files_are_one_line(tmp_path):
    coded, ds = _study()
    cases = [
        (tmp_path / "absent.csv", "no such file"),
        (_write(tmp_path / "header.csv", []), "no rows"),
        (_write(tmp_path / "nocoder.csv", _rows("ana", ANA), [c for c in SHEET_COLUMNS if c != "coder"]), "['coder']"),
    ]
    wide = tmp_path / "wide.csv"
    wide.write_text(",".join(SHEET_COLUMNS) + "\n" + ",".join(["x"] * (len(SHEET_COLUMNS) + 2)) + "\n")
    cases.append((wide, "row 2: 15 cells, the header has 13"))
    binary = tmp_path / "binary.csv"
    binary.write_bytes(b"\xff\xfe\x00episode_id")
    cases.append((binary, "not a UTF-8 CSV file"))
    for path, words in cases:
        with pytest.raises(CodesError) as err:
            read_codes(path, coded, ds)
        assert str(path) in str(err.value) and words in str(err.value), str(err.value)


def test_a_coder_without_a_codes_file_is_refused():
    from sphri.config import load_schema
    from sphri.sessions.schema import ScenarioStudySchema

    with pytest.raises(ConfigError, match="coder"):
        load_schema(ScenarioStudySchema, {"coder": "ana"})
    assert load_schema(ScenarioStudySchema, {"coder": "ana", "codes": "x.csv"}).coder == "ana"
