"""A ratings table's entry points: reading and validating it, its exclusions, power table and
whole report, each finding the table's design (`analysis.designs`); GENEA files and simulated tables.
"""
