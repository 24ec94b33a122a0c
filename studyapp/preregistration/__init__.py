"""A study's pre-registration: its plan, locked when it first opens, and every deviation from it since.

    contents.py      the plan: design and settings, rules, systems, controls, planned analysis
    participants.py  the planned number of participants: the targets' or the design's power
    lock.py          freezing it (canonical JSON, SHA-256, time), recording deviations, the plan as data
    words.py         the plan and its deviations in words, for the plan page and the report

Opening a study (the monitor's button, the settings form, the demo: whatever saves
``is_open`` true) locks its plan once; every later save of the study, its systems or
its controls compares the plan as it now stands with the locked plan and its recorded
deviations, and records each part that differs (``lock.py`` says why a log and not a
diff at reading time). The signals are connected in ``studyapp.apps``.
"""
