"""Live touch classification on a stream of skin frames (no I/O).

:class:`LiveClassifier` takes frames one at a time (``push``) and returns
predictions:

- ``window``: every ``stride`` frames, the model's prediction on the last
  L frames (a sliding window; L = the model's window length);
- ``touch``: once per touch, the prediction on the L frames from the
  touch's onset: the same alignment as the training windows (L frames
  from contact onset).

Touch detection must ignore sensor noise (e.g. 2 % salt-and-pepper: a few
random taxels on in every frame). Noise rarely hits the same taxel in
consecutive frames while a touch holds its taxels, so the activity of frame
t is the sum over taxels of the minimum of the last ``persist`` frames; a
touch starts when it reaches the threshold, and its onset is the first
frame of that run (``persist - 1`` frames back). On grids, a frame with
``cluster_taxels`` connected taxels on (8-connected, :mod:`sphri.adjacency`) also starts a touch (short pats and
taps that no taxel holds for ``persist`` frames). A lone-taxel candidate
that falls back before ``confirm`` frames above the threshold stays
tentative: a later trigger within its window replaces it (noise blips do
not hide the real touch that follows). A touch ends after
``release_frames`` frames below the threshold. ``onset_activity=0``
calibrates the threshold from the first ``calibrate_frames`` frames,
assumed mostly untouched: median + 4 robust standard deviations (1.4826
MAD) + 0.5 of their activity.

On the synthetic pipeline's streams (``+debug=fast data.participants=6
data.repetitions=3``: 144 trials, 2 % salt-and-pepper, data v3) this finds
121 of 144 touches with 4 false touches in 12.8 minutes of stream: every one
of the 120 trials whose touch reaches the defaults' limits (a taxel held
``persist`` frames, or ``cluster_taxels`` connected taxels in a frame), none
of the 4 trials without contact, and 1 of the 20 fainter pokes, taps and pats
(noise). ``persist=2`` finds 131 with 57 false touches, ``cluster_taxels=3``
129 with 50 (tests/hardware/test_hw_acceptance.py checks the limits).

Latency is measured from the arrival of the newest frame in the window
(the caller's ``received`` time, ``time.perf_counter()`` clock) to the
end of the prediction.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from sphri.adjacency import Adjacency, taxel_adjacency
from sphri.export.model_file import ModelBundle
from sphri.hardware.settings import SkinLiveSettings as _L  # the defaults, stated once


@dataclass(frozen=True)
class Prediction:
    """One classification of a window of L frames."""

    kind: str
    """"window" (sliding) or "touch" (onset-aligned)."""
    frame: int
    """Index (in pushed frames) of the window's last frame."""
    start: int
    """Index of the window's first frame (the onset for a touch)."""
    label: int
    gesture: str
    probability: float
    latency_ms: float
    """From the newest frame's arrival to the end of the prediction."""
    compute_ms: float
    """Time spent in the model alone."""

    def line(self) -> str:
        what = "TOUCH " if self.kind == "touch" else "window"
        return (
            f"{what} frames {self.start:6d}-{self.frame:6d}  {self.gesture:<7s} p={self.probability:.2f}  "
            f"latency {self.latency_ms:6.1f} ms (model {self.compute_ms:.1f} ms)"
        )

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def largest_cluster(frame: np.ndarray, adjacency: Adjacency) -> int:
    """Taxels in the largest connected group of taxels >= 0.5 of one frame (N,) (:mod:`sphri.adjacency`)."""
    on = (np.asarray(frame) >= 0.5).reshape(1, -1)
    n_on = int(on.sum())
    if n_on <= 1:
        return n_on
    return int(adjacency.largest_component(on)[0])


class LiveClassifier:
    """Sliding-window and per-touch predictions of a :class:`ModelBundle` on pushed frames.

    Touch detection (see the module docstring): ``onset_activity`` (0 =
    calibrate), ``persist`` frames a taxel must hold, ``confirm`` frames above
    the threshold that make a lone-taxel candidate a touch, ``cluster_taxels``
    (grids only; 0 = off): a frame with this many connected taxels on is a
    touch at once (short pats and taps that no taxel holds for ``persist``
    frames). A lone-taxel candidate that is not confirmed stays tentative:
    the next trigger within the window replaces it.
    """

    def __init__(
        self,
        bundle: ModelBundle,
        stride: int = 6,
        onset_activity: float = _L.onset_taxels,
        calibrate_frames: int = _L.calibrate_frames,
        release_frames: int = _L.release_frames,
        persist: int = _L.persist,
        confirm: int = 2,
        cluster_taxels: int = _L.cluster_taxels,
    ) -> None:
        if stride < 1:
            raise ValueError(f"stride={stride} must be >= 1")
        if not 1 <= persist <= bundle.window_length:
            raise ValueError(f"persist={persist} must be in [1, window length {bundle.window_length}]")
        self.bundle = bundle
        self.length = int(bundle.window_length)
        self.n_taxels = bundle.n_taxels
        self.stride = int(stride)
        self.onset_activity = float(onset_activity)
        self.calibrate_frames = int(calibrate_frames)
        self.release_frames = int(release_frames)
        self.persist = int(persist)
        self.confirm = max(1, int(confirm))
        grid = bundle.geometry.grid_shape
        self.grid_shape = (int(grid[0]), int(grid[1])) if grid is not None else None
        self.cluster_taxels = int(cluster_taxels) if self.grid_shape is not None else 0
        # 8-connected touch clusters (grids; v wraps where the chart does)
        self.adjacency = taxel_adjacency(bundle.geometry, diagonal=True) if self.cluster_taxels else None
        # ring of the last 2L frames (a touch window may start up to L frames back)
        self._cap = 2 * self.length
        self._ring = np.zeros((self._cap, self.n_taxels), dtype=np.float32)
        self._received = np.zeros(self._cap, dtype=np.float64)
        self.count = 0
        self._calib: list[float] = []
        self._calib_cluster: list[int] = []
        self._onset: int | None = None
        self._above = 0
        self._weak = False
        self._tentative = False
        self._quiet = 0
        self._armed = True
        self.compute_ms: list[float] = []

    @property
    def threshold(self) -> float | None:
        """Persistent activity that marks a touch (None while calibrating)."""
        if self.onset_activity > 0:
            return self.onset_activity
        if len(self._calib) < self.calibrate_frames:
            return None
        a = np.asarray(self._calib)
        med = float(np.median(a))
        mad = float(np.median(np.abs(a - med))) * 1.4826  # robust to a touch during calibration
        return med + 4.0 * mad + 0.5

    @property
    def cluster_threshold(self) -> int:
        """Connected taxels that mark a touch (0 = off); raised above what calibration saw often."""
        if not self.cluster_taxels:
            return 0
        if self._calib_cluster:
            return max(self.cluster_taxels, int(max(self._calib_cluster)) + 2)
        return self.cluster_taxels

    def reset(self) -> None:
        """Forget the frames (e.g. after a reconnect); the calibration is kept."""
        self.count = 0
        self._onset = None
        self._tentative = False
        self._quiet = 0
        self._armed = True

    def push(self, values: np.ndarray, received: float | None = None) -> list[Prediction]:
        """Add one frame (N,) in [0, 1]; returns the predictions it completes."""
        v = np.asarray(values, dtype=np.float32)
        if v.shape != (self.n_taxels,):
            raise ValueError(f"frame has shape {v.shape}; the model expects ({self.n_taxels},) taxels")
        received = time.perf_counter() if received is None else received
        i = self.count
        self._ring[i % self._cap] = v
        self._received[i % self._cap] = received
        self.count += 1
        out: list[Prediction] = []
        if self.count < self.persist:
            activity = 0.0
        else:
            idx = np.arange(i - self.persist + 1, i + 1) % self._cap
            activity = float(self._ring[idx].min(axis=0).sum())
        cluster = largest_cluster(v, self.adjacency) if self.adjacency is not None else 0
        thr = self.threshold
        if thr is None:
            if self.count >= self.persist:
                self._calib.append(activity)
                self._calib_cluster.append(cluster)
        else:
            self._detect(i, activity, thr, cluster)
        if self._onset is not None and i - self._onset + 1 == self.length:
            out.append(self._predict("touch", self._onset, i))
            self._onset = None
            self._tentative = False
            if self._quiet >= self.release_frames:
                self._armed = True
        if self.count >= self.length and (i + 1 - self.length) % self.stride == 0:
            out.append(self._predict("window", i + 1 - self.length, i))
        return out

    def _detect(self, i: int, activity: float, thr: float, cluster: int) -> None:
        cthr = self.cluster_threshold
        by_cluster = cthr > 0 and cluster >= cthr
        by_persist = activity >= thr
        if by_persist or by_cluster:
            self._quiet = 0
            start = i - self.persist + 1 if by_persist else i
            if self._armed or self._tentative:
                # a new touch, or a real one after an unconfirmed lone-taxel blip
                self._onset, self._armed, self._tentative, self._above = start, False, False, 1
                self._weak = not by_cluster and activity < thr + 1.0
            else:
                self._above += 1
                if by_persist and self._onset is not None and start < self._onset:
                    self._onset = start  # the taxels held since before the cluster formed
            return
        if self._onset is not None and self._weak and self._above < self.confirm:
            self._tentative = True  # kept unless another trigger comes before its window is full
        self._quiet += 1
        if not self._armed and self._quiet >= self.release_frames and self._onset is None:
            self._armed = True

    def _predict(self, kind: str, start: int, end: int) -> Prediction:
        x = self._ring[np.arange(start, start + self.length) % self._cap][None]
        t0 = time.perf_counter()
        p = self.bundle.predict_proba(x)[0]
        t1 = time.perf_counter()
        k = int(np.argmax(p))
        labels = self.bundle.labels
        compute = (t1 - t0) * 1000.0
        self.compute_ms.append(compute)
        latency = (t1 - self._received[end % self._cap]) * 1000.0
        return Prediction(kind, end, start, k, labels[k] if k < len(labels) else str(k), float(p[k]), latency, compute)


def auto_stride(frame_rate_hz: float, target_hz: float = 15.0) -> int:
    """Frames between sliding predictions for about ``target_hz`` predictions per second."""
    return max(1, int(math.floor(frame_rate_hz / target_hz)))
