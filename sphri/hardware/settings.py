"""Settings of the hardware commands (their ``key=value`` parser is :mod:`sphri.args`).

The hardware commands (``sphri glove|skin``) are
entry points beside the pipeline, not stages. Each has a settings dataclass
below (a :class:`sphri.config.Schema` like the pipeline's: typed fields with
defaults, units in the names, ranges as field metadata (:func:`sphri.config.setting`)
and rules across fields in ``check``, errors naming the key; the simulators and
``sphri.export.train`` keep theirs beside their code, on the same base). Command lines are
``key=value`` pairs (or ``--key value``): keys of the settings are taken here, and, for the
commands that compose a config, everything else (``+debug=fast``, ``robot=nao_child``,
``data.seed=3``) is passed to :func:`sphri.config.compose` for the pipeline part.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from sphri.config import Schema, require, require_choice, setting
from sphri.hardware.skin_protocol import MAX_TAXELS


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
    """``sphri glove replay``: play one trial's contacts to a glove."""

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
class SkinStreamSettings(Schema):
    """What reading a skin's stream shares (``skin record`` and ``skin live``): the port and when to stop."""

    port: str = "???"
    """Device or pyserial URL of the skin."""
    baud: int = setting(1_000_000, lo=300, hi=12_000_000)
    """Bits per second (ignored by USB CDC devices and socket://)."""
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


@dataclass
class SkinRecordSettings(SkinStreamSettings):
    """``sphri skin record``: save a skin's frames to a file."""

    out: str = "???"
    """Output recording (.npz), written atomically; also on Ctrl+C, SIGTERM or a lost port. Checked before
    reading; an existing file is refused (never replaced)."""
    taxels: int = setting(0, lo=0, hi=4096)
    """Expected taxel count N (0 = grid's H*W, or without a grid the count most of the first consensus_frames carry)."""
    grid: str = ""
    """Grid shape HxW of the layout (rows along the link), e.g. 18x6; empty = not a grid. Sets the taxel count."""
    consensus_frames: int = setting(9, lo=1, hi=1000)
    """With neither taxels nor grid: the count carried by consensus_frames // 2 + 1 of the first valid frames."""
    chunk_frames: int = setting(50, lo=1, hi=100_000)
    """Every frame is written to ``<out>.partial`` as it is read (a killed recorder loses none); the file
    is fsynced every chunk_frames frames or sync_interval_s seconds, whichever comes first (a power cut)."""
    sync_interval_s: float = setting(1.0, lo=0.0, hi=3600.0)
    """Longest time between two fsyncs of ``<out>.partial`` (seconds)."""

    def check(self) -> None:
        _port(self.port)
        require(self.out not in ("", "???"), "out", self.out, "an output path, e.g. out=recording.npz")
        grid = parse_grid(self.grid)
        if grid is not None:
            n = grid[0] * grid[1]
            require(
                n <= MAX_TAXELS,
                "grid",
                self.grid,
                f"H*W={n} taxels, more than the {MAX_TAXELS} a skin frame can carry (the taxels= limit)",
            )
        if grid is not None and self.taxels:
            require(grid[0] * grid[1] == self.taxels, "grid", self.grid, f"H*W must equal taxels={self.taxels}")


@dataclass
class SkinLiveSettings(SkinStreamSettings):
    """``sphri skin live``: classify touch on a streaming skin."""

    model: str = "???"
    """Model file (from sphri export), or with allow_remote=true an MLflow artifact URI runs:/<run_id>/<path>."""
    tracking_uri: str | None = None
    """MLflow tracking URI for runs:/ models (None = sqlite:///outputs/mlflow.db, the pipeline's default)."""
    allow_remote: bool = False
    """Fetch a remote model (runs:/, models:/, http://...); off by default: only local files are read."""
    allow_unverified: bool = False
    """Load a model file signed with a key although no key (SPHRI_MODEL_KEY) is configured to check it."""
    plugins: list[str] = field(default_factory=list)
    """Packages whose model classes a model file may name (e.g. [labext]); sphri's own models need none."""
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

    def check(self) -> None:
        _port(self.port)
        require(self.model not in ("", "???"), "model", self.model, "a model file or runs:/<run_id>/<path>")
        self.show = _switch(self.show, "show", ("all", "touches", "off"))
