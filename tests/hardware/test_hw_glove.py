"""Glove: contacts -> actuators, message scheduling, the driver on loop:// and against the simulator."""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sphri.args import ArgsError, parse_known
from sphri.config import ConfigError
from sphri.hardware.actuators import ActuatorMap, capsule_actuator, part_depths
from sphri.hardware.glove import GloveDriver, PlannedMessage, play, schedule, select_trial
from sphri.hardware.glove_protocol import ACTUATORS, GloveDecoder
from sphri.hardware.settings import GloveReplaySettings
from sphri.hardware.sim_glove import GloveSimSettings, GloveSimulator
from sphri.hardware.transport import Link, PortError, make_endpoint, open_port, start_in_thread


def glove_state(messages: list[PlannedMessage], n_frames: int, frame_rate_hz: float) -> np.ndarray:
    """(n_frames + 1, 6) level the glove runs at each frame, from the messages' semantics."""
    frame_ms = 1000.0 / frame_rate_hz
    level = np.zeros((n_frames + 1, 6), dtype=np.int64)
    by_frame = {m.frame: m for m in messages}
    cur = np.zeros(6, dtype=np.int64)
    until = np.zeros(6)
    for f in range(n_frames + 1):
        t = f * frame_ms
        if f in by_frame:
            m = by_frame[f]
            cur = np.array(m.intensity)
            until = t + np.array(m.pulse_ms, dtype=float)
        level[f] = np.where(until - t > 1e-9, cur, 0)
    return level


def test_capsules_map_to_their_parts(hand):
    act = capsule_actuator(hand)
    assert [ACTUATORS[a] for a in act] == list(hand.fingers)


def test_unknown_hand_part_is_refused(hand):
    import dataclasses

    odd = dataclasses.replace(hand, fingers=("tail",) + hand.fingers[1:])
    with pytest.raises(ValueError, match="tail"):
        capsule_actuator(odd)


def test_part_depths_take_the_deepest_capsule_of_each_part(hand, contacts_from_rows):
    # capsules 7, 8 are index; 0 is palm; 4 is thumb
    c = contacts_from_rows(20, [(3, 7, 0.002), (3, 8, 0.005), (4, 0, 0.001), (9, 4, 0.003), (15, 7, 0.004)])
    d = part_depths(c, hand, start=2, n_frames=10)  # frames 2..11
    assert d.shape == (10, 6)
    idx, palm, thumb = ACTUATORS.index("index"), ACTUATORS.index("palm"), ACTUATORS.index("thumb")
    assert d[1, idx] == pytest.approx(0.005)
    assert d[2, palm] == pytest.approx(0.001)
    assert d[7, thumb] == pytest.approx(0.003)
    assert (d > 0).sum() == 3  # frame 15 lies outside the range
    with pytest.raises(ValueError, match="outside"):
        part_depths(c, hand, start=15, n_frames=10)


def test_intensity_scales_with_depth_and_is_constant_when_asked():
    depth = np.zeros((4, 6))
    depth[1, 0], depth[2, 0], depth[3, 0] = 1e-6, 0.005, 0.05
    lvl, rem = ActuatorMap(intensity_min=80, intensity_max=240, depth_full_m=0.01).desired(depth, 90.0)
    assert lvl[0, 0] == 0 and rem[0, 0] == 0
    assert lvl[1, 0] == 80 and lvl[2, 0] == 160 and lvl[3, 0] == 240
    assert (rem[1:, 0] == 60).all()
    lvl, _ = ActuatorMap(intensity="constant", intensity_max=200).desired(depth, 90.0)
    assert list(lvl[1:, 0]) == [200, 200, 200]


def test_onset_pulses_run_out_by_themselves():
    depth = np.zeros((30, 6))
    depth[2:25, 1] = 0.004  # one long contact
    lvl, rem = ActuatorMap(trigger="onset", pulse_ms=50).desired(depth, 100.0)  # 10 ms per frame
    on = np.flatnonzero(lvl[:, 1] > 0)
    assert list(on) == [2, 3, 4, 5, 6]
    assert rem[2, 1] == pytest.approx(50) and rem[6, 1] == pytest.approx(10)


def test_actuator_map_validates():
    with pytest.raises(ConfigError, match="pulse_ms"):
        ActuatorMap(pulse_ms=0)
    with pytest.raises(ConfigError, match="intensity_min"):
        ActuatorMap(intensity_min=200, intensity_max=100)
    with pytest.raises(ConfigError, match="trigger"):
        ActuatorMap(trigger="always")


@settings(max_examples=50, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    trigger=st.sampled_from(["contact", "onset"]),
    pulse_ms=st.integers(5, 200),
    rate=st.sampled_from([30.0, 72.0, 90.0]),
)
def test_schedule_makes_the_glove_follow_the_contacts(seed, trigger, pulse_ms, rate):
    """Simulating the glove from the messages gives the desired level at every frame."""
    rng = np.random.default_rng(seed)
    n = 80
    touching = rng.random((n, 6)) < 0.3
    touching = touching | np.roll(touching, 1, axis=0)  # some longer contacts
    depth = np.where(touching, rng.uniform(0.001, 0.02, (n, 6)), 0.0)
    lvl, rem = ActuatorMap(trigger=trigger, pulse_ms=pulse_ms).desired(depth, rate)
    msgs = schedule(lvl, rem, rate)
    state = glove_state(msgs, n, rate)
    np.testing.assert_array_equal(state[:n], np.where(rem > 0, lvl, 0))
    assert (state[n] == 0).all()  # everything off after the trial
    assert len({m.frame for m in msgs}) == len(msgs)  # at most one message per frame


def test_schedule_sends_only_on_change_and_refresh():
    depth = np.zeros((100, 6))
    depth[10:90, 2] = 0.01  # constant contact: on, refreshes, off
    lvl, rem = ActuatorMap(pulse_ms=100).desired(depth, 100.0)  # 10 ms frames
    msgs = schedule(lvl, rem, 100.0)
    frames = [m.frame for m in msgs]
    assert frames[0] == 10 and frames[-1] == 90
    assert msgs[-1].intensity == (0,) * 6
    gaps = np.diff(frames[:-1])
    assert (gaps >= 8).all()  # refreshed shortly before each 100 ms pulse runs out, not every frame
    assert len(msgs) < 15


def test_schedule_rate_limit():
    depth = np.zeros((90, 6))
    depth[:, 0] = np.linspace(0.0001, 0.01, 90)  # intensity changes every frame
    lvl, rem = ActuatorMap().desired(depth, 90.0)
    msgs = schedule(lvl, rem, 90.0, rate_hz=30.0)
    t = np.array([m.t_s for m in msgs])
    assert np.diff(t).min() >= 1 / 30 - 1e-9
    assert 25 <= len(msgs) <= 32


def test_driver_dry_run_on_loopback_prints_and_reads_back():
    depth = np.zeros((40, 6))
    depth[5:20, 1] = 0.006
    depth[8:12, 5] = 0.002
    lvl, rem = ActuatorMap().desired(depth, 90.0)
    msgs = schedule(lvl, rem, 90.0)
    lines: list[str] = []
    with Link("loop://") as link:
        report = play(msgs, GloveDriver(link, acks=False, show=lines.append), realtime=False)
    assert report.sent == len(msgs) == len(lines)
    assert report.echoed == len(msgs) and report.echo_mismatch == 0
    # each line: the bytes sent, then the command they encode
    parsed = [re.search(r"((?:[0-9a-f]{2} ){25}[0-9a-f]{2})  (ACTUATE .*)$", ln) for ln in lines]
    assert all(parsed), lines
    decoded = GloveDecoder().feed(b"".join(bytes.fromhex(m.group(1)) for m in parsed))
    assert [d.describe() for d in decoded] == [m.group(2) for m in parsed]


def test_realtime_play_paces_messages():
    msgs = [PlannedMessage(i * 9, i * 0.1, (100, 0, 0, 0, 0, 0), (60, 0, 0, 0, 0, 0)) for i in range(4)]
    with Link("loop://") as link:
        report = play(msgs, GloveDriver(link, acks=False), realtime=True)
    assert 0.28 <= report.seconds < 0.6


@pytest.mark.parametrize("port", ["pty", "socket://127.0.0.1:0"])
def test_driver_counts_missing_acks_against_the_simulator(port):
    sim = GloveSimulator(
        GloveSimSettings(port=port, ack_drop_rate=0.3, seed=5),
        make_endpoint(GloveSimSettings(port=port)),
        say=lambda m: None,
    )
    th = start_in_thread(sim)
    depth = np.zeros((60, 6))
    depth[3:50, 0] = np.linspace(0.001, 0.012, 47)  # intensity changes: a message per frame
    lvl, rem = ActuatorMap().desired(depth, 90.0)
    msgs = schedule(lvl, rem, 90.0)
    try:
        with Link(sim.endpoint.url) as link:
            report = play(msgs, GloveDriver(link, acks=True, ack_timeout_s=0.3), realtime=False)
    finally:
        sim.stop.set()
        th.join(5)
    led = sim.ledger
    assert led.commands == report.sent == len(msgs)
    assert led.acks_dropped > 0
    assert report.acked == led.acks_sent
    assert report.missing_acks == led.acks_dropped
    assert report.unexpected_acks == 0 and led.decoder["skipped_bytes"] == 0


def test_missing_port_gives_a_clear_error():
    with pytest.raises(PortError, match="/dev/ttyNOPE0"):
        open_port("/dev/ttyNOPE0")


def test_replay_settings_parse_and_validate():
    s, rest = parse_known(
        GloveReplaySettings, ["port=loop://", "trial=2", "pulse_ms=80", "+debug=fast", "robot=nao_child", "-m"]
    )
    assert (s.trial, s.pulse_ms) == (2, 80) and rest == ["+debug=fast", "robot=nao_child", "-m"]
    assert parse_known(GloveReplaySettings, ["--trigger", "onset", "--realtime", "data.seed=3"])[0].trigger == "onset"
    with pytest.raises(ArgsError, match=r"^pulse_ms=0 is invalid: must be in \[1, 65535\]$"):
        parse_known(GloveReplaySettings, ["pulse_ms=0"])
    with pytest.raises(ArgsError, match="^trial=abc is invalid: must be an integer$"):
        parse_known(GloveReplaySettings, ["trial=abc"])
    with pytest.raises(ArgsError, match="^acks='maybe' is invalid"):  # Schema.check
        parse_known(GloveReplaySettings, ["acks=maybe"])
    with pytest.raises(
        ArgsError, match=r"^trigger='onst' is invalid: allowed values: \['contact', 'onset'\]$"
    ):  # setting(choices=...)
        parse_known(GloveReplaySettings, ["trigger=onst"])


def test_select_trial():
    import pandas as pd

    trials = pd.DataFrame({"participant": ["p1", "p1", "p2", "p2", "p2"]})
    assert select_trial(trials, 1, "p2") == 3
    assert select_trial(trials, 4, None) == 4
    with pytest.raises(ConfigError, match="p3"):
        select_trial(trials, 0, "p3")
    with pytest.raises(ConfigError, match="trial=2"):
        select_trial(trials, 2, "p1")
