"""The one exception type of `analysis`: input that cannot be analysed as given.

It subclasses ValueError so callers that already catch ValueError keep working; the
message always says which column, system or file is at fault and what to do about it.
"""


class AnalysisInputError(ValueError):
    """Ratings or motion that break the documented schema or a precondition."""
