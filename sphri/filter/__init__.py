"""Skin-side filters on the noisy windows: temporal (``filter=debounce|median``), spatial (``filter=despeckle``).

A tactile skin's electronics filter their readings before anything
classifies them; this stage sits between noise and the model. See
:mod:`sphri.filter.components`.
"""
