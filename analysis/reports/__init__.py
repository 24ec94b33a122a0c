"""The tables, figures and report folders: the single design's report, the report of the designs
with several clips on a page, the leaderboard's and the rater models'; the designs hand themselves in.
"""
