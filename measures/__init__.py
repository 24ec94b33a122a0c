"""What ``generation`` and ``analysis`` both measure on a human figure: the length unit
and up axis of motion capture (``units``) and which joints are the feet and how fast the
weight-bearing one moves (``feet``).

It sits below both libraries so that neither imports the other: numpy and the standard
library only, never ``generation``, ``analysis``, ``studyapp``, torch or Django
(``tests/test_structure.py`` holds every package to its rules).
"""
