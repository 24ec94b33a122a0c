"""What a study's ratings say: the monitor and its figures, the analysis reports and
their files, the ratings export with its rules, and the control adherence of its motion."""
