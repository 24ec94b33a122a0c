"""Statistics of rated and compared systems: ANOVA and Tukey HSD, signed ranks, sign tests and
Wilson intervals of preferences, Holm corrections, the participant minimums and the power closed forms.
"""
