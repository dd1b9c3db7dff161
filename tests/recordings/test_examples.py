"""``sphri synthesize what=openxr``: example OpenXR logs of the synthetic study, listed and labelled synthetic."""

from __future__ import annotations

import csv

from sphri.command import main
from sphri.types import GESTURES


def test_example_logs_are_listed_labelled_synthetic_and_import(tmp_path, capsys):
    out = tmp_path / "logs"
    assert main(["synthesize", "what=openxr", f"out={out}", "data.participants=1", "data.seed=4"]) == 0
    assert "wrote 8 logs" in capsys.readouterr().out
    rows = list(csv.DictReader((out / "manifest.csv").open()))
    assert sorted(r["gesture"] for r in rows) == sorted(GESTURES)
    assert {(r["participant"], r["link"], r["rate_hz"]) for r in rows} == {("1", "arm", "30")}
    assert sorted(p.name for p in out.glob("*.csv")) == sorted([*(r["file"] for r in rows), "manifest.csv"])
    readme = (out / "README.txt").read_text()
    assert readme.startswith("SYNTHETIC") and "seed 4: 8 logs, 1 participants" in readme
    first = rows[0]
    argv = ["import", "openxr", str(out / first["file"]), f"out={tmp_path / 'ds'}", f"link={first['link']}"]
    argv += [f"participant={first['participant']}", f"gesture={first['gesture']}", f"rate_hz={first['rate_hz']}"]
    assert main(argv) == 0
    assert f"as trial 0001_{first['gesture']} of participant_01 on arm" in capsys.readouterr().out


def test_example_logs_refuse_a_folder_that_is_not_empty(tmp_path, capsys):
    (tmp_path / "logs").mkdir()
    (tmp_path / "logs" / "mine.csv").write_text("time\n")
    assert main(["synthesize", "what=openxr", f"out={tmp_path / 'logs'}"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"sphri synthesize: invalid config: out={tmp_path / 'logs'} is invalid: ")
    assert "not empty" in err and "overwrite=true" in err and "\n" not in err
    assert (tmp_path / "logs" / "mine.csv").read_text() == "time\n"
    (tmp_path / "logs" / "mine.csv").unlink()  # an empty folder is taken
    assert main(["synthesize", "what=openxr", f"out={tmp_path / 'logs'}", "data.participants=1"]) == 0
    (tmp_path / "logs" / "mine.csv").write_text("time\n")
    assert main(["synthesize", "what=openxr", f"out={tmp_path / 'logs'}", "data.participants=1", "overwrite=true"]) == 0
    assert not (tmp_path / "logs" / "mine.csv").exists()  # replaced whole, never mixed
    assert (tmp_path / "logs" / "manifest.csv").exists()


def test_example_logs_refuse_a_hand_without_the_openxr_capsules(tmp_path, hand, capsys):
    from dataclasses import replace

    from sphri.data.format import write_hand_definition

    keep = [i for i, n in enumerate(hand.names) if not n.startswith("thumb")]
    fields = ("radius_m", "height_m", "axis", "center_offset_m")
    small = replace(
        hand,
        names=tuple(hand.names[i] for i in keep),
        fingers=tuple(hand.fingers[i] for i in keep),
        **{f: getattr(hand, f)[keep] for f in fields},
    )
    write_hand_definition(small, tmp_path / "hand.json")
    argv = ["synthesize", "what=openxr", f"out={tmp_path / 'logs'}", f"hand.definition_path={tmp_path / 'hand.json'}"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("sphri synthesize: invalid config: hand is invalid for what=openxr: it lacks the capsules ")
    assert "thumb1, thumb2, thumb3;" in err and "\n" not in err
    assert not (tmp_path / "logs").exists()
