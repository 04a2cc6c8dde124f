"""Benchmarks for ``saw-ros bench``: one module per area, each with ``KEYS`` (the JSON keys it
reports) and ``run(quick: bool) -> dict``. They measure rates and ratios in one run, never assert.
"""
