"""sphri's Hydra sweeper plugin (``hydra/sweeper=sphri``): see :mod:`.sphri_sweeper`.

Hydra instantiates plugins only from the ``hydra_plugins`` namespace package,
so the sweeper lives here; its logic is in :mod:`sphri.tracking.parent`.
"""
