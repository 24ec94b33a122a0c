"""Objective metrics of motion clips: footsteps, bone lengths, smoothness, Fréchet distance,
inception scores, t-SNE, and reading clips (`motion_io`); they take arrays, not ratings.
"""
