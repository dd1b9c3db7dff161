"""Settings of the hardware commands and their ``key=value`` command-line parser.

The hardware commands (``python -m sphri.hardware.glove|skin|simulate``) are
entry points beside the pipeline, not stages. Each has a settings dataclass
below (a :class:`sphri.config.Schema` like the pipeline's: typed fields with
defaults, units in the names, ranges as field metadata (:func:`sphri.config.setting`)
and rules across fields in ``check``, errors naming the key; ``train_export``
keeps its own beside its code). Command lines are
Hydra-like ``key=value`` pairs: keys of the settings are taken here, and
everything else (``+debug=fast``, ``robot=nao_child``, ``data.seed=3``) is
passed to :func:`sphri.config.compose` for the pipeline part.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from sphri.config import ConfigError, Schema, require, require_choice, setting

T = TypeVar("T")


def _port(value: str) -> None:
    require(
        isinstance(value, str) and value.strip() != "",
        "port",
        value,
        "a device path (/dev/ttyUSB0) or pyserial URL (loop://, socket://host:port)",
    )


def _switch(value, key: str, choices: tuple[str, ...]) -> str:
    """Normalize an on/off/auto setting: YAML reads off/no as false and on/yes as true."""
    text = str(value).strip().lower() if value is not None else "off"
    text = {"true": "on", "yes": "on", "false": "off", "no": "off", "none": "off", "null": "off"}.get(text, text)
    require_choice(key, text, choices)
    return text


def parse_grid(text: str) -> tuple[int, int] | None:
    """``"18x6"`` -> (18, 6); ``""`` -> None. Raises ConfigError naming ``grid``."""
    if not text:
        return None
    parts = text.lower().replace("*", "x").split("x")
    ok = len(parts) == 2 and all(p.strip().isdigit() and int(p) > 0 for p in parts)
    require(ok, "grid", text, "HxW with positive integers, e.g. 18x6 (rows along the link x columns around it)")
    return int(parts[0]), int(parts[1])


@dataclass
class GloveReplaySettings(Schema):
    """``python -m sphri.hardware.glove replay``: play one trial's contacts to a glove."""

    port: str = "loop://"
    """Device or pyserial URL; ``loop://`` is a dry run that prints the command stream."""
    baud: int = setting(115200, lo=300, hi=12_000_000)
    """Bits per second (the glove's Bluetooth serial module setting)."""
    glove_id: int = setting(1, lo=0, hi=255)
    """Glove id carried in every message (0..255), e.g. 0 = left, 1 = right."""
    trial: int = setting(0, lo=0)
    """0-based trial index: among ``participant``'s trials, or among all trials when unset."""
    participant: str | None = None
    """Participant whose trial is played (e.g. participant_01); None = index all trials."""
    realtime: bool = True
    """Pace messages at the tracking rate; false sends as fast as possible."""
    rate_hz: float = setting(0.0, lo=0.0, hi=1000.0)
    """Most messages per second (0 = the dataset's tracking frame rate)."""
    pulse_ms: int = setting(60, lo=1, hi=65535)
    """Vibration pulse length in milliseconds."""
    trigger: str = setting("contact", choices=("contact", "onset"))
    """contact: pulse while the part touches (refreshed); onset: one pulse per contact onset."""
    intensity: str = setting("depth", choices=("depth", "constant"))
    """depth: scale with penetration depth; constant: always intensity_max."""
    intensity_min: int = setting(80, lo=1, hi=255)
    """Intensity (1..255) of a barely touching contact (intensity=depth)."""
    intensity_max: int = setting(255, lo=1, hi=255)
    """Intensity (1..255) at depth_full_m and beyond, or always (constant)."""
    depth_full_m: float = setting(0.01, lo=0.0, hi=0.5, lo_open=True)
    """Penetration depth in metres that gives intensity_max."""
    acks: str | None = "auto"
    """Wait for acknowledgements: on, off, or auto (off for loop://, on otherwise)."""
    ack_timeout_s: float = setting(0.25, lo=0.0, hi=60.0, lo_open=True)
    """An ACK later than this (seconds) counts as missing."""
    show: str | None = "auto"
    """Print every message: on, off, or auto (on for loop://)."""

    def check(self) -> None:
        _port(self.port)
        require(
            self.intensity_min <= self.intensity_max,
            "intensity_min",
            self.intensity_min,
            f"must be <= intensity_max={self.intensity_max}",
        )
        self.acks = _switch(self.acks, "acks", ("auto", "on", "off"))
        self.show = _switch(self.show, "show", ("auto", "on", "off"))


@dataclass
class SkinRecordSettings(Schema):
    """``python -m sphri.hardware.skin record``: save a skin's frames to a file."""

    port: str = "???"
    """Device or pyserial URL of the skin."""
    out: str = "???"
    """Output recording (.npz), written atomically; also on Ctrl+C, SIGTERM or a lost port. Checked before
    reading; an existing file is refused (never replaced)."""
    baud: int = setting(1_000_000, lo=300, hi=12_000_000)
    """Bits per second (ignored by USB CDC devices and socket://)."""
    taxels: int = setting(0, lo=0, hi=4096)
    """Expected taxel count N (0 = grid's H*W, or without a grid the count most of the first consensus_frames carry)."""
    grid: str = ""
    """Grid shape HxW of the layout (rows along the link), e.g. 18x6; empty = not a grid. Sets the taxel count."""
    consensus_frames: int = setting(9, lo=1, hi=1000)
    """With neither taxels nor grid: the count carried by consensus_frames // 2 + 1 of the first valid frames."""
    frames: int = setting(0, lo=0)
    """Stop after this many good frames (0 = no limit)."""
    duration_s: float = setting(0.0, lo=0.0)
    """Stop after this many seconds (0 = no limit)."""
    idle_s: float = setting(0.0, lo=0.0)
    """Stop when no frame arrived for this many seconds (0 = wait forever)."""
    reconnect: bool = False
    """Retry a vanished port (unplugged device) instead of stopping."""
    reconnect_timeout_s: float = setting(30.0, lo=0.0)
    """Give up reconnecting after this many seconds (0 = never)."""
    start_command: bool = True
    """Send the protocol's START message on (re)connect (skins may ignore it)."""
    chunk_frames: int = setting(50, lo=1, hi=100_000)
    """Every frame is written to ``<out>.partial`` as it is read (a killed recorder loses none); the file
    is fsynced every chunk_frames frames or sync_interval_s seconds, whichever comes first (a power cut)."""
    sync_interval_s: float = setting(1.0, lo=0.0, hi=3600.0)
    """Longest time between two fsyncs of ``<out>.partial`` (seconds)."""

    def check(self) -> None:
        _port(self.port)
        require(self.out not in ("", "???"), "out", self.out, "an output path, e.g. out=recording.npz")
        grid = parse_grid(self.grid)
        if grid is not None and self.taxels:
            require(grid[0] * grid[1] == self.taxels, "grid", self.grid, f"H*W must equal taxels={self.taxels}")


@dataclass
class SkinLiveSettings(Schema):
    """``python -m sphri.hardware.skin live``: classify touch on a streaming skin."""

    port: str = "???"
    """Device or pyserial URL of the skin."""
    model: str = "???"
    """Model file (from train_export), or with allow_remote=true an MLflow artifact URI runs:/<run_id>/<path>."""
    tracking_uri: str | None = None
    """MLflow tracking URI for runs:/ models (None = sqlite:///outputs/mlflow.db, the pipeline's default)."""
    allow_remote: bool = False
    """Fetch a remote model (runs:/, models:/, http://...); off by default: only local files are read."""
    baud: int = setting(1_000_000, lo=300, hi=12_000_000)
    """Bits per second (ignored by USB CDC devices and socket://)."""
    stride: int = setting(0, lo=0, hi=10_000)
    """Frames between sliding-window predictions (0 = about 15 per second)."""
    onset_taxels: float = setting(0.0, lo=0.0)
    """Touch activity (taxels held on for ``persist`` frames) that marks an onset; 0 = calibrate."""
    calibrate_frames: int = setting(30, lo=1)
    """Untouched frames at the start used to calibrate onset_taxels when it is 0."""
    release_frames: int = setting(10, lo=1)
    """Frames below the onset activity that end a touch (re-arms onset detection)."""
    persist: int = setting(3, lo=1, hi=100)
    """Frames a taxel must stay on to count toward touch activity (filters flickering noise)."""
    cluster_taxels: int = setting(6, lo=0, hi=4096)
    """Grids: this many connected taxels on in one frame also mark a touch (0 = off)."""
    fill_gaps: int = setting(5, lo=0, hi=1000)
    """Up to this many frames lost in a row (sequence gap) are filled by holding the last frame (0 = off)."""
    out: str = ""
    """Also write every prediction as a JSON line to this file (empty = no file)."""
    show: str | None = "all"
    """Print: all (sliding windows and touches), touches (one line per touch), off."""
    frames: int = setting(0, lo=0)
    """Stop after this many good frames (0 = no limit)."""
    duration_s: float = setting(0.0, lo=0.0)
    """Stop after this many seconds (0 = no limit)."""
    idle_s: float = setting(0.0, lo=0.0)
    """Stop when no frame arrived for this many seconds (0 = wait forever)."""
    reconnect: bool = False
    """Retry a vanished port instead of stopping."""
    reconnect_timeout_s: float = setting(30.0, lo=0.0)
    """Give up reconnecting after this many seconds (0 = never)."""
    start_command: bool = True
    """Send the protocol's START message on (re)connect."""

    def check(self) -> None:
        _port(self.port)
        require(self.model not in ("", "???"), "model", self.model, "a model file or runs:/<run_id>/<path>")
        self.show = _switch(self.show, "show", ("all", "touches", "off"))


@dataclass
class SimulateSettings(Schema):
    """``python -m sphri.hardware.simulate skin|glove``: emulate a device."""

    port: str = "pty"
    """pty (a pseudo-terminal; its path is printed and linked at ``link``) or socket://HOST:PORT to listen on."""
    link: str = ""
    """pty only: a stable symlink to the pseudo-terminal (re-pointed after a simulated replug)."""
    seed: int = setting(0, lo=0)
    """Seeds the injected faults (and the pattern source)."""
    report: str = ""
    """Write what was sent (good frames, faults) or received as JSON to this file."""
    # skin
    source: str = setting("pipeline", choices=("pipeline", "pattern"))
    """skin: pipeline (encoded synthetic trials of the composed config) or pattern (moving blobs)."""
    trials: int = 8
    """skin, pipeline source: number of trials streamed (-1 = all selected)."""
    participant: str | None = None
    """skin, pipeline source: stream only this participant's trials."""
    taxels: int = setting(0, lo=0, hi=4096)
    """skin, pattern source: taxel count (0 = from grid)."""
    grid: str = "18x6"
    """skin, pattern source: grid shape HxW."""
    frames: int = setting(600, lo=1)
    """skin, pattern source: frames to stream."""
    rate_hz: float = setting(0.0, lo=0.0, hi=10_000.0)
    """skin: frames per second (0 = the dataset's frame rate, 90 for patterns)."""
    realtime: bool = True
    """skin: pace frames at rate_hz; false streams as fast as the link takes them."""
    format: str = setting("auto", choices=("auto", "u8", "u16", "bits"))
    """skin: value format u8, u16, bits, or auto (bits for binary encoders, u8 otherwise)."""
    gap_s: float = setting(0.5, lo=0.0, hi=60.0)
    """skin, pipeline source: untouched (noise-only) seconds before each trial."""
    garbage_rate: float = setting(0.0, lo=0.0, hi=1.0)
    """skin: probability per frame of a burst of random bytes before it."""
    corrupt_rate: float = setting(0.0, lo=0.0, hi=1.0)
    """skin: probability per frame of a flipped byte (bad checksum)."""
    drop_rate: float = setting(0.0, lo=0.0, hi=1.0)
    """skin: probability per frame of not sending it (sequence gap)."""
    truncate_rate: float = setting(0.0, lo=0.0, hi=1.0)
    """skin: probability per frame of sending only its first part."""
    wrong_count_rate: float = setting(0.0, lo=0.0, hi=1.0)
    """skin: probability per frame of a valid frame with a wrong taxel count instead."""
    unplug_after_s: float = setting(0.0, lo=0.0)
    """skin: simulate unplugging after this many seconds of streaming (0 = never)."""
    unplug_s: float = setting(1.0, lo=0.0, hi=600.0)
    """skin: how long the device stays unplugged (seconds)."""
    wait_start: bool = True
    """skin: wait for the host's START message before streaming (and after a replug)."""
    hold_s: float = setting(1.0, lo=0.0, hi=600.0)
    """skin: keep the port open this long after the last frame (seconds)."""
    # glove
    ack_drop_rate: float = setting(0.0, lo=0.0, hi=1.0)
    """glove: probability of not acknowledging a command."""
    ack_delay_s: float = setting(0.0, lo=0.0, hi=10.0)
    """glove: delay before each acknowledgement (seconds)."""
    duration_s: float = setting(0.0, lo=0.0)
    """glove: stop after this many seconds (0 = until the host disconnects)."""

    def check(self) -> None:
        require(self.port == "pty" or self.port.startswith("socket://"), "port", self.port, "pty or socket://HOST:PORT")
        require(self.trials == -1 or self.trials >= 1, "trials", self.trials, "a count >= 1, or -1 for all")
        parse_grid(self.grid)
        total = self.corrupt_rate + self.drop_rate + self.truncate_rate + self.wrong_count_rate
        require(
            total <= 1.0,
            "corrupt_rate",
            self.corrupt_rate,
            f"corrupt + drop + truncate + wrong_count rates must sum to <= 1 (got {total:g})",
        )


def field_names(cls: type) -> list[str]:
    return [f.name for f in dataclasses.fields(cls)]


def parse_cli(argv: Sequence[str], cls: type[T], pipeline: bool) -> tuple[T, list[str]]:
    """Split ``key=value`` arguments into ``cls`` settings and pipeline overrides.

    Keys that are fields of ``cls`` set them (typed and range-checked); the
    rest are returned as pipeline overrides when ``pipeline`` is true, and
    refused otherwise. Raises :class:`ConfigError` naming the key.
    """
    names = field_names(cls)
    mine: list[str] = []
    rest: list[str] = []
    for arg in argv:
        if "=" not in arg:
            raise ConfigError(f"argument {arg!r} is invalid: expected key=value (settings: {', '.join(names)})")
        key = arg.split("=", 1)[0]
        (mine if key in names else rest).append(arg)
    if rest and not pipeline:
        raise ConfigError(
            f"unknown setting(s) {', '.join(a.split('=', 1)[0] for a in rest)}; settings: {', '.join(names)}"
        )
    try:
        node = OmegaConf.merge(OmegaConf.structured(cls), OmegaConf.from_dotlist(mine))
        settings = OmegaConf.to_object(node)
    except ConfigError:
        raise
    except OmegaConfBaseException as exc:
        key = getattr(exc, "full_key", None) or "?"
        first = str(exc).strip().splitlines()[0]
        raise ConfigError(f"{key}: {first}") from None
    return settings, rest  # type: ignore[return-value]


def describe(settings: Any) -> str:
    """``key=value`` of every setting (for logs)."""
    return " ".join(f"{f.name}={getattr(settings, f.name)}" for f in dataclasses.fields(settings))
