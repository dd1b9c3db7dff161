"""``sphri code``: the coding sheet lists the study's own episodes, its replays show them, the filled sheet drives the
study (``experiment.scenario_study.codes``), and the page works offline in a real browser (headless chromium)."""

from __future__ import annotations

import base64
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from sphri.command import main
from sphri.sessions.codes import SHEET_COLUMNS
from sphri.types import GESTURES

#: A small, fast study: one training region, two repetitions per gesture.
FAST = [
    "+debug=fast",
    "experiment.scenario_study.gesture_repetitions=2",
    "experiment.scenario_study.gesture_regions=[torso_front_upper]",
]


@pytest.fixture(scope="module")
def sheet(written, tmp_path_factory):
    out = tmp_path_factory.mktemp("sheet")
    runs = tmp_path_factory.mktemp("coding_runs")
    overrides = [*FAST, f"output_dir={runs}", f"cache.dir={runs / 'cache'}"]
    assert main(["code", f"sessions={written}", f"out={out}", *overrides]) == 0
    table = pd.read_csv(out / "codes.csv", keep_default_na=False)
    html = (out / "coding_sheet.html").read_text()
    return SimpleNamespace(root=written, out=out, runs=runs, overrides=overrides, table=table, html=html)


def _study_episodes(sheet):
    """The study's own coded episodes of the same sessions and settings."""
    from sphri.config import compose
    from sphri.pipeline import open_cache
    from sphri.sessions.labelling import segment
    from sphri.sessions.schema import study_settings

    cfg = compose(["+experiment=scenario_study", "data=sessions", f"data.root={sheet.root}", *sheet.overrides])
    return segment(cfg, study_settings(cfg), open_cache(cfg))


def _page_data(html: str) -> dict:
    block = re.search(r'<script type="application/json" id="replay-data">(.*?)</script>', html, re.S)
    assert block, "no replay data in the page"
    return json.loads(block.group(1))


def _array(b64: str, dtype: str) -> np.ndarray:
    return np.frombuffer(base64.b64decode(b64), dtype=np.dtype(dtype).newbyteorder("<"))


def test_the_sheet_lists_the_studys_coded_episodes_with_empty_codes(sheet):
    _, _, ds, _, _, _, coded, _, _ = _study_episodes(sheet)
    t = sheet.table
    assert list(t.columns) == list(SHEET_COLUMNS) and len(t) == len(coded) >= 6
    first = ds.sessions["start"].to_numpy()[coded["session"].to_numpy()]
    assert t["start_frame"].tolist() == (coded["start_frame"] - first).tolist()  # frames within the session
    assert t["end_frame"].tolist() == (coded["end_frame"] - first).tolist()
    assert t["part"].tolist() == coded["dominant_part"].tolist()
    assert t["episode_id"].tolist() == [
        f"{r.participant}/{r.scenario}/r{r.repetition}/e{r.episode}" for r in coded.itertuples()
    ]
    assert t["episode_id"].is_unique and set(t["suggestion"]) <= set(GESTURES)
    assert (t["gesture"] == "").all() and (t["coder"] == "").all()
    # the page: every episode once as a section, once in the index, its suggestion marked as one
    for eid in t["episode_id"]:
        assert sheet.html.count(f'data-episode-id="{eid}"') == 2, eid
    assert sheet.html.count('<span class="suggestion">suggestion (gesture model, not a code)') == len(t)


def test_the_page_is_self_contained(sheet):
    assert not re.search(r"\b(https?|ftp|wss?)://|//[a-z0-9.-]+\.[a-z]{2,}", sheet.html, re.I)  # no URL, no CDN
    assert not re.search(r"\ssrc\s*=", sheet.html)  # no script, image or frame fetched from anywhere
    assert set(re.findall(r'href="(.)', sheet.html)) <= {"#"}  # links only within the page


def test_the_replay_shows_the_hands_on_the_touched_link(sheet):
    """The capsules in the link's frame, decoded from the page, match an independent transform; the contact points
    the page draws in a frame are that frame's contacts on the link, and a capsule of that frame touches them."""
    from scipy.spatial.transform import Rotation

    from sphri.hand.kinematics import capsule_segments

    _, _, ds, bc, _, _, coded, _, _ = _study_episodes(sheet)
    data = _page_data(sheet.html)
    radius_mm = np.asarray(data["radius_mm"])
    assert len(data["episodes"]) == len(coded)
    for k, e in enumerate(coded.itertuples()):
        ep = data["episodes"][k]
        assert data["links"][ep["link"]]["name"] == e.dominant_link and ep["part"] == e.dominant_part
        s0 = int(ds.sessions["start"].iat[e.session])
        frames = s0 + ep["first_frame"] + ep["stride"] * np.arange(ep["n"])
        assert frames[0] <= e.start_frame and frames[-1] >= e.end_frame - ep["stride"]
        caps = _array(ep["caps"], "int16").reshape(ep["n"], 2, -1, 2, 3).astype(float)
        f = ep["episode"][0]  # the episode's first frame, the hand in the world moved into the link's frame
        li = ds.links.index(e.dominant_link)
        p0, p1 = capsule_segments(ds.hand_poses[frames[f]], ds.hand)
        pose = ds.link_poses[frames[f], li].astype(float)
        inv = Rotation.from_quat(pose[3:]).inv()
        want = np.stack([inv.apply(p0 - pose[:3]), inv.apply(p1 - pose[:3])], axis=2) * 1000.0
        assert np.abs(caps[f] - want).max() <= 1.0, e.Index
        dot_frame = _array(ep["dot_frame"], "uint16")
        dots = _array(ep["dots"], "int16").reshape(-1, 3).astype(float)
        assert dots.shape[0] > 0 and dot_frame.max() < ep["n"]
        j = int(np.argmax(np.bincount(dot_frame)))  # the frame with most contact points
        rows = (bc.frame == frames[j]) & (bc.link == li)
        assert sorted(map(tuple, dots[dot_frame == j])) == sorted(map(tuple, np.round(bc.point_m[rows] * 1000)))
        ends = caps[j].reshape(-1, 2, 3)  # (hands x capsules, 2, 3): the page draws either hand's contact points
        a, b, rad = ends[:, 0], ends[:, 1], np.tile(radius_mm, 2)
        d = []
        for p in dots[dot_frame == j]:  # distance of each contact point to the nearest capsule surface
            t = np.clip(((p - a) * (b - a)).sum(1) / np.maximum(((b - a) ** 2).sum(1), 1e-9), 0, 1)
            d.append(np.min(np.linalg.norm(p - (a + t[:, None] * (b - a)), axis=1) - rad))
        assert min(d) < 4.0, (e.Index, d)  # a capsule touches the surface there (deeper ones press it in)


def test_code_refuses_bad_input_in_one_line(sheet, tmp_path, capsys):
    filled = tmp_path / "filled"
    filled.mkdir()
    t = sheet.table.copy()
    t.loc[0, ["gesture", "coder"]] = ["hit", "ana"]
    t.to_csv(filled / "codes.csv", index=False)
    empty = tmp_path / "nothing"
    empty.mkdir()
    for args, words in (
        ([f"sessions={sheet.root}", f"out={filled}"], ("already holds 1 codes", "codes.csv")),
        ([f"sessions={empty}", f"out={tmp_path / 'o'}"], (f"sessions={empty}", "no sessions.json")),
        ([f"sessions={sheet.root}", f"out={tmp_path / 'o'}", "replay_hz=0"], ("replay_hz=0", "[1, 1000]")),
    ):
        assert main(["code", *args]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("sphri code: ") and all(w in err[0] for w in words), err
    assert pd.read_csv(filled / "codes.csv", keep_default_na=False)["gesture"].iat[0] == "hit"  # kept


def test_filled_codes_drive_the_study_and_two_coders_get_kappa(sheet, tmp_path, capsys):
    from sklearn.metrics import cohen_kappa_score

    t = sheet.table
    n = len(t)
    ana = [GESTURES[(3 * k) % len(GESTURES)] for k in range(n)]  # not the model's labels
    ben = list(ana)
    ben[0], ben[1] = ana[1], ana[0]
    a = t.assign(gesture=ana, coder="ana")
    b = t.assign(gesture=ben, coder="ben")
    codes = tmp_path / "codes.csv"
    pd.concat([a, b]).to_csv(codes, index=False)
    out = tmp_path / "study"
    study = [
        "coverage",
        "+experiment=scenario_study",
        "data=sessions",
        f"data.root={sheet.root}",
        *sheet.overrides,
        "experiment.scenario_study.render=false",
        "experiment.scenario_study.by=gesture",
        "mlflow=false",
    ]
    assert main([*study, f"experiment.scenario_study.codes={codes}", f"out={out}"]) == 0
    printed = capsys.readouterr().out
    hist = pd.read_csv(out / "gesture_histogram.csv")
    got = hist.groupby("gesture")["count"].sum()
    for g in GESTURES:
        assert got[g] == ana.count(g), g  # the person's codes, not the model's
    per = hist.set_index(["scenario", "gesture"])["count"]
    for s, g in zip(t["scenario"], ana):
        assert per[s, g] >= 1
    coded = pd.read_csv(out / "coded_episodes.csv", keep_default_na=False)
    assert coded["gesture"].tolist() == ana and coded["suggestion"].tolist() == t["suggestion"].tolist()
    maps = np.load(out / "density_maps.npz", allow_pickle=True)
    # the by-gesture maps are the coded gestures (and "unlabelled" for sessions the study codes no episode of)
    assert set(ana) <= set(maps["scenarios"]) <= set(ana) | {"unlabelled"}
    summary = json.loads((out / "summary.json").read_text())["human_codes"]
    pair = summary["agreement"][0]
    assert (pair["coder_a"], pair["coder_b"], pair["n_episodes"]) == ("ana", "ben", n)
    assert pair["kappa"] == pytest.approx(cohen_kappa_score(ana, ben))
    assert f"agree on {n - 2} of {n} episodes" in printed and f"Cohen's kappa {pair['kappa']:.2f}" in printed

    bad = pd.concat([a, b])
    bad.iloc[n + 2, bad.columns.get_loc("gesture")] = "stroak"  # ben's third row: spreadsheet row n + 4
    bad.to_csv(codes, index=False)
    assert main([*study, f"experiment.scenario_study.codes={codes}", f"out={tmp_path / 'bad'}"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in err[0], err
    assert all(w in err[0] for w in (str(codes), f"row {n + 4}", "'gesture'", "'stroak'", "stroke")), err[0]


# --- the page in a real browser --------------------------------------------------------------------------------------

FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--proxy-server=127.0.0.1:9",  # a proxy to nowhere: any fetch the page tried would fail
    "--enable-logging=stderr",
    "--v=0",
]


#: Where Debian's package puts the browser.
CHROMIUM = Path("/usr/bin/chromium")


def _chromium() -> str:
    """The browser, or a skip naming the Debian package (a failure on CI, which installs it: .ci/run)."""
    path = str(CHROMIUM) if CHROMIUM.is_file() else shutil.which("chromium")
    if path:
        return path
    if os.environ.get("CI"):
        pytest.fail("no chromium on CI: .ci/run installs the Debian package chromium before the tests")
    pytest.skip("no browser: install the Debian package chromium (apt-get install chromium) to test the page")


def _browse(page: Path, profile: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [_chromium(), *FLAGS, f"--user-data-dir={profile}", *args],
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_without_a_browser_the_browser_tests_skip_but_fail_on_ci(monkeypatch, tmp_path):
    monkeypatch.setattr(sys.modules[__name__], "CHROMIUM", tmp_path / "no-chromium")
    monkeypatch.setattr(shutil, "which", lambda name: None)
    monkeypatch.delenv("CI", raising=False)
    with pytest.raises(pytest.skip.Exception, match="Debian package chromium"):
        _chromium()
    monkeypatch.setenv("CI", "true")
    with pytest.raises(pytest.fail.Exception, match="no chromium on CI"):
        _chromium()


def test_the_page_replays_offline_in_chromium(sheet, tmp_path):
    t = sheet.table
    last = len(t) - 1
    page = sheet.out / "coding_sheet.html"
    run = _browse(page, tmp_path / "profile", "--virtual-time-budget=3000", "--dump-dom", f"{page.as_uri()}#ep{last}")
    assert run.returncode == 0, run.stderr[-3000:]
    dom = run.stdout
    assert "Uncaught" not in run.stderr and "ERR_" not in run.stderr, run.stderr[-3000:]
    ids = re.findall(r'<section class="episode" id="ep(\d+)" data-index="\d+" data-episode-id="([^"]+)"', dom)
    assert [e for _, e in ids] == t["episode_id"].tolist()  # every episode listed, in the sheet's order
    outputs = re.findall(r'<output class="frame" data-frame="(\d+)" data-played="(\d+)">([^<]*)<', dom)
    assert len(outputs) == len(t)
    frame, played, text = outputs[last]  # the episode the page was opened at plays (and loops)
    n = _page_data(sheet.html)["episodes"][last]["n"]
    assert int(played) >= 20 and int(frame) == int(played) % n, outputs[last]
    assert f"/ {n} · session frame" in text
    assert int(outputs[0][1]) == 0  # the first is off screen: it waits


def test_the_page_draws_the_replay(sheet, tmp_path):
    """A screenshot of the first episode: the hands (blue, green) and the touched part (orange) are drawn."""
    from PIL import Image

    page = sheet.out / "coding_sheet.html"
    shot = tmp_path / "sheet.png"
    run = _browse(
        page,
        tmp_path / "profile",
        "--window-size=1000,2400",
        "--virtual-time-budget=1500",
        f"--screenshot={shot}",
        page.as_uri(),
    )
    assert run.returncode == 0 and shot.is_file(), run.stderr[-3000:]
    r, g, b = np.moveaxis(np.asarray(Image.open(shot).convert("RGB")).astype(int), 2, 0)
    blue = (b > r + 60) & (b > g + 20)  # the left hand's capsules, over white or over the surface
    green = (g > r + 60) & (g > b + 60)  # the right hand's
    orange = (r > 100) & (r > 1.6 * g) & (g > 2.5 * b)  # the touched part, lit and shaded
    assert blue.sum() + green.sum() > 500 and orange.sum() > 200, (blue.sum(), green.sum(), orange.sum())
