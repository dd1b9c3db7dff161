"""Oracles and toy data for tests and benchmarks, kept apart from the components users pick.

- :mod:`sphri.testing.contact_reference`: brute-force float64 capsule-vs-mesh
  contact and the hard test sets the exact kernel is checked against.
- :mod:`sphri.testing.raster_reference`: supersampled rasterization references
  for the encoders.
- :mod:`sphri.testing.synthetic_contacts`: :class:`~sphri.types.Contacts` with
  realistic statistics, made without the contact stage.
- :mod:`sphri.testing.toy_windows`: gesture windows drawn directly (no hands,
  no contact), for model tests and benchmarks.
- :mod:`sphri.testing.bf16`: how far a grid encoder's bf16 pass is from float32 (oneDNN's defect).
- :mod:`sphri.testing.runs`: a :class:`~sphri.types.RunMeta` for tests that
  log or report runs without running a job.

Nothing in the pipeline imports this package.
"""
