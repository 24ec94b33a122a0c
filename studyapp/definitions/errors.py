"""The one error of a study definition: what is wrong, in which file, on which line."""

from __future__ import annotations


class DefinitionError(ValueError):
    """A study definition that cannot become a study. ``problems`` are (line, message)
    pairs (line None where the problem is the whole file); the message names the file
    and each problem's line, one problem after another on one line of text."""

    def __init__(self, source: str, problems: list[tuple[int | None, str]]) -> None:
        self.source, self.problems = source, problems
        super().__init__("; ".join(self.lines()))

    def lines(self) -> list[str]:
        """Each problem as ``source:line: message``."""
        return [f"{self.source}:{line}: {message}" if line else f"{self.source}: {message}"
                for line, message in self.problems]
