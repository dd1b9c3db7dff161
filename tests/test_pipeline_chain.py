"""One chain, injectable inputs: every caller's pipeline is ``make_pipeline`` (sphri.pipeline).

Values handed in memory (``inputs=``) are keyed by their content and the stages below them are
computed by the same code as a job's; a streamed skin (sphri.hardware.source) carries exactly the
noisy windows the offline chain made.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sphri.cache import StageCache
from sphri.config import compose
from sphri.pipeline import Memo, content_key, make_pipeline

#: One participant, one repetition of each gesture; windows longer than some trials' contact
#: (padded slots: the streamed tail) and a seed other than the default.
SMALL = ["+debug=fast", "data.participants=1", "data.repetitions=1", "window.frames=200", "seed=3"]


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return StageCache(tmp_path_factory.mktemp("chain_cache"))


def _offline(cache, *extra):
    return make_pipeline(compose([*SMALL, *extra]), cache)


def test_streamed_readings_are_the_offline_windows(cache):
    """Every streamed frame of a trial's window, its padded slots included, is the offline noise stage's."""
    from sphri.hardware.source import encode_trials

    offline = _offline(cache).get("noise")
    clean = _offline(cache, "noise=none").get("noise")
    assert (offline.x != clean.x).sum() > 100, "the noise must change the windows, else the test proves nothing"
    rows = np.array([5, 0, 6, 2], dtype=np.int64)  # a few trials, out of order: not the offline batch
    stream = encode_trials(_offline(cache), rows, gap_s=0.2)  # a pipeline of its own, as a command opens it
    window_of = {int(r): w for w, r in enumerate(offline.trial_row)}
    compared = padded = 0
    for i, row in enumerate(rows.tolist()):
        onset = int(stream.onsets[i])
        assert onset >= 0 and row in window_of, "every trial of the small config has contact"
        streamed = np.concatenate([stream.values[i][onset:], stream.tail[i]])[: offline.x.shape[1]]
        np.testing.assert_array_equal(streamed, offline.x[window_of[row]], err_msg=f"trial row {row}")
        compared += 1
        padded += len(stream.tail[i])
    assert compared == len(rows) and padded > 0, "the padded slots (the tail) must be compared too"
    # frames no window holds get draws of their own: the gap before each trial is noise on nothing
    assert all(g.shape == (6, stream.n_taxels) for g in stream.gap)


def test_streamed_readings_follow_the_run_seed(cache):
    from sphri.hardware.source import encode_trials

    a = encode_trials(_offline(cache), [1])
    b = encode_trials(_offline(cache, "seed=4"), [1])
    assert not np.array_equal(a.values[0], b.values[0])


def test_data_handed_in_memory_goes_through_the_same_chain(cache):
    job = _offline(cache)
    dataset = job.get("data")
    given = make_pipeline(job.cfg, cache, inputs={"data": dataset})
    assert given.records["data"].source == "given"
    assert given.key("data") == content_key("data", dataset) != job.key("data")
    np.testing.assert_array_equal(given.get("filter").x, job.get("filter").x)
    # content-keyed: the same content finds the stages below it in the cache, other content does not
    again = make_pipeline(job.cfg, cache, inputs={"data": dataclasses.replace(dataset)})
    assert again.key("contact") == given.key("contact")
    again.get("contact")
    assert again.records["contact"].source == "cache"
    moved = dataclasses.replace(dataset, poses=dataset.poses + np.float32(1e-3))
    assert make_pipeline(job.cfg, cache, inputs={"data": moved}).key("contact") != given.key("contact")


def test_given_keeps_the_values_upstream_of_the_inputs(cache):
    job = _offline(cache)
    plan, _, _ = job.get("plan"), job.get("contact"), job.get("data")
    sub = dataclasses.replace(plan, kept=plan.kept & (np.arange(len(plan.kept)) < 3))
    part = job.given({"plan": sub})
    assert part.records["data"].source == part.records["contact"].source == "memory"
    assert part.key("layout") == job.key("layout") and part.key("encode") != job.key("encode")
    full = job.get("noise")
    np.testing.assert_array_equal(part.get("noise").x, full.x[np.isin(full.trial_row, np.flatnonzero(sub.kept))])


def test_a_memo_shares_stages_between_pipelines(cache):
    memo = Memo()
    first = make_pipeline(compose(SMALL), cache, memo=memo)
    robot = first.get("robot")
    second = make_pipeline(compose([*SMALL, "layout.res=5"]), cache, memo=memo)
    assert second.get("robot") is robot and second.records["robot"].source == "memory"


def test_inputs_are_checked(cache):
    cfg = compose(SMALL)
    with pytest.raises(ValueError, match=r"inputs \['dta'\] are not stages of the chain"):
        make_pipeline(cfg, cache, inputs={"dta": None})
    with pytest.raises(TypeError, match=r"inputs\['data'\]: expected .*GestureDataset.*, got dict"):
        make_pipeline(cfg, cache, inputs={"data": {}})
    with pytest.raises(TypeError, match=r"inputs\['robot'\]: a object cannot be keyed by its content"):
        make_pipeline(cfg, cache, inputs={"robot": object()})
