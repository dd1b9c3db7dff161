"""A lab's own sphri components, in a package of its own (used by tests/test_plugins.py)."""
