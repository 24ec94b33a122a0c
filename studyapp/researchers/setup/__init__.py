"""Building a study before it opens: its pages (``*_views``: the study, systems and controls,
questions, stimuli) and what they call: the forms, the checklist and the expected duration,
whether it may open, the preview, and editing, removing, copying and ordering what it holds."""
