"""bench/profile_suite.py: py-spy's collapsed stacks of a suite run, given to kinds of work, processes and tests."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[2] / "bench"
sys.path.insert(0, str(BENCH))

from profile_suite import markdown, profile  # noqa: E402

# the command line names a test file whose name holds forked_cli.py: frames, not command lines, classify
PYTEST = 'process 10:"python -m pytest -n 2 tests/test_forked_cli.py";process 11:"python -u -c import sys'
WORKER = f'{PYTEST};exec(eval(sys.stdin.readline())))";<module> (xdist/remote.py:400)'
TEST = "pytest_pyfunc_call (_pytest/python.py:160);test_small_study (tests/models/test_cnn_gru.py:306)"
FORKSERVER = f'{PYTEST};process 12:"python -B -c from multiprocessing.forkserver import main'
LINES = [
    # in a test, a CNN-GRU fit: 30 samples
    f"{WORKER};{TEST};run (sphri/pipeline.py:80);CnnGru.fit (sphri/models/cnn_gru.py:461);backward (torch/_tensor.py:1) 30",
    # in a test, Hydra's composition inside an import: composition comes first in the order
    f"{WORKER};{TEST};compose (sphri/config.py:480);ConfigLoaderImpl.load_configuration (hydra/x.py:133);"
    "_find_and_load (<frozen importlib._bootstrap>:1) 20",
    # a forked CLI child importing: 25 samples
    f"{FORKSERVER};_child (forked_cli.py:90);<module> (sphri/__main__.py:1);_find_and_load (<frozen importlib._bootstrap>:1) 25",
    # a loky worker of a sweep started by a forked child
    f'{FORKSERVER};process 13:"python -m joblib.externals.loky.backend.popen_loky_posix --process-name W";'
    "<module> (joblib/externals/loky/backend/popen_loky_posix.py:1);_find_and_load (<frozen importlib._bootstrap>:1) 15",
    # a plain subprocess (its temporary folder and port numbers fall together), other work
    f'{PYTEST};process 14:"python -m sphri +debug=fast output_dir=/tmp/pytest-of-root/pytest-7/t0/o port=12345";'
    "main (sphri/__main__.py:250);dijkstra (scipy/x.py:1) 10",
    "",  # an empty line and a truncated one are skipped
    f"{WORKER};{TEST};CnnGru.fit (sphri/models/cnn_gru.py:461)",
]


#: Samples of LINES per kind of work, process and test.
EXPECTED = {
    "kinds": {"CNN-GRU training and prediction": 30, "Hydra composition": 20, "imports": 40, "other": 10},
    "processes": {
        "pytest worker (tests in process)": 50,
        "forked CLI child (tests/forked_cli.py)": 25,
        "loky worker (parallel sweep or folds)": 15,
        "python -m sphri +debug=fast output_dir=TMP port=N": 10,
    },
    "tests": {"test_cnn_gru.py::test_small_study": 50, "(not in a test's own process)": 50},
}


def test_samples_go_to_their_kind_process_and_test():
    result = profile(LINES, rate_hz=10.0)
    assert result["samples"] == 100 and result["cpu_s"] == 10.0
    for table, expected in EXPECTED.items():
        assert {r["name"]: r["samples"] for r in result[table]} == expected, table
        assert all(r["cpu_s"] == r["samples"] / 10.0 for r in result[table])
    assert abs(sum(r["share"] for r in result["kinds"]) - 1.0) < 1e-12


def test_each_sample_has_an_origin_within_its_kind_and_process():
    """The innermost sphri or test frame before the kind's own first frame; an import also names the module
    it imports (the first ``<module>`` frame after the import machinery), ``?`` where a stack has none."""
    mlflow = (
        f"{WORKER};{TEST};MlflowTracker.client (sphri/tracking/mlflow_tracker.py:263);"
        "_find_and_load (<frozen importlib._bootstrap>:1);<module> (mlflow/__init__.py:44);"
        "_find_and_load (<frozen importlib._bootstrap>:1);<module> (fastapi/__init__.py:7) 5"
    )
    origins = {r["name"]: r["samples"] for r in profile([*LINES, mlflow], rate_hz=10.0)["origins"]}
    worker, forked = "pytest worker (tests in process)", "forked CLI child (tests/forked_cli.py)"
    assert origins == {
        f"CNN-GRU training and prediction · {worker} · run (sphri/pipeline.py)": 30,
        f"Hydra composition · {worker} · compose (sphri/config.py)": 20,
        f"imports · {forked} · <module> (sphri/__main__.py) -> ?": 25,
        "imports · loky worker (parallel sweep or folds) · ? -> ?": 15,
        "other · python -m sphri +debug=fast output_dir=TMP port=N · main (sphri/__main__.py)": 10,
        f"imports · {worker} · MlflowTracker.client (sphri/tracking/mlflow_tracker.py) -> <module> (mlflow/__init__.py)": 5,
    }


def test_the_script_writes_its_tables_from_a_stacks_file(tmp_path):
    """``--stacks``: no suite run; JSON and Markdown in ``--out`` with the machine; a missing file is
    one line and exit 2."""
    stacks = tmp_path / "prof.txt"
    stacks.write_text("\n".join(LINES) + "\n")
    out = tmp_path / "bench"
    done = subprocess.run(
        [sys.executable, str(BENCH / "profile_suite.py"), "--stacks", str(stacks), "--wall", "12", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    data = json.loads((out / "suite_profile.json").read_text())
    assert data["samples"] == 100 and data["wall_s"] == 12 and data["machine"]["cpu_model"]
    text = (out / "suite_profile.md").read_text()
    assert "| Hydra composition | 2 | 20.0 % |" in text and data["machine"]["cpu_flags"] in text
    assert text == markdown(data) + "\n"
    missing = subprocess.run(
        [sys.executable, str(BENCH / "profile_suite.py"), "--stacks", str(tmp_path / "none.txt"), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert missing.returncode == 2 and "no such file" in missing.stderr and len(missing.stderr.splitlines()) == 1
