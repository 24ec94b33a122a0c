"""What a study's ratings say: its pages (``result_views``: the monitor, the exports, the plan
and the report) and what they call: the monitor and its figures, the analysis reports and
their files, the ratings export with its rules, and the control adherence of its motion."""
