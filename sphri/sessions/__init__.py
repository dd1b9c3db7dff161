"""Free-interaction sessions with a whole robot: data, whole-body contact, episodes, the scenario study.

- :mod:`sphri.sessions.format`: :class:`SessionDataset`, the on-disk format
  (parquet + manifest per participant), :func:`write_sessions`,
  :class:`SessionData` (``data=sessions``, the validating loader).
- :mod:`sphri.sessions.synthetic`: :class:`SyntheticSessions`
  (``data=synthetic_sessions``) driven by the scenario priors table
  (``conf/scenario_priors/reachy2021.yaml``).
- :mod:`sphri.sessions.contact`: one contact pass of both hands against every
  link at its per-frame pose, with bounding-sphere culling.
- :mod:`sphri.sessions.episodes`: episode segmentation (>= 2 s without contact ends one).
- :mod:`sphri.sessions.gestures`: a gesture model trained in the same job labels episodes.
- :mod:`sphri.sessions.labelling`: the study's coded episodes and their labels, one computation for
  the study and the coding sheet.
- :mod:`sphri.sessions.coding_sheet` (``sphri code``) with :mod:`sphri.sessions.replay`: a page of
  episode replays and a CSV for people to code gestures by hand; :mod:`sphri.sessions.codes` reads
  the filled CSV back into the study (``codes=PATH``) with Cohen's kappa between coders.
- :mod:`sphri.sessions.study`: whole-body maps, SWD tests, ranking, placement, report.
"""
