"""Rankings from pairwise votes: Bradley–Terry, the leaderboard (Elo with bootstrap intervals),
the next pair of an adaptive study and graded votes; built on `analysis.stats`.
"""
