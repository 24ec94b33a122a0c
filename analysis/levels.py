"""The conventional levels every table and plan of the analysis uses, in a module of
their own so that the study app's models can name them without importing the analysis."""

ALPHA = 0.05  # the tests' significance level unless a report is asked for another
POWER = 0.8  # the power the tables of ratings and participants needed plan for
