"""Robot morphologies: parametric built-ins, mesh files and URDFs -> :class:`sphri.types.Robot`."""
