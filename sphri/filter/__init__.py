"""Skin-side temporal filters on the noisy windows (``filter=none|debounce|median``).

A tactile skin's electronics filter their readings before anything
classifies them; this stage sits between noise and the model. See
:mod:`sphri.filter.components`.
"""
