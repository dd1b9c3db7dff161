"""sphri: design robot tactile skins from interaction data."""

__version__ = "0.1.0"
