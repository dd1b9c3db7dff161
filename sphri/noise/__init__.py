"""Sensor noise on skin readings, deterministic per (seed, trial, frame).

Components (``noise=...``, ``apply(frames, frame_index, trial_key, seed) ->
Frames``): ``salt_pepper`` (the paper's, p = 0.02), ``gaussian``,
``dead_taxels``, ``crosstalk`` and ``none``; see :mod:`sphri.noise.components`.
"""
