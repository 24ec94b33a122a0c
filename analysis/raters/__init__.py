"""Models of the raters: the mixed models (per-cell, crossed LMM, cumulative link) and rater
agreement; built on `analysis.stats`.
"""
