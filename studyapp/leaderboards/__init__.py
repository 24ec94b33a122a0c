"""Leaderboards that span studies: a researcher's board, its rounds (pairwise studies), the fit on
every round's votes, and the board's public page."""
