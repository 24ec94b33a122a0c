"""The command lines of ``python -m analysis``: `main` (report, objective, ...), their shared
options and the ranking commands; above every other room.
"""

from analysis.cli.main import main, parser

__all__ = ["main", "parser"]
