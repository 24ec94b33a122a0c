"""Building a study before it opens: the study pages' forms, the checklist and the
expected duration, whether it may open, the preview, and editing, removing, copying and
ordering what it holds."""
