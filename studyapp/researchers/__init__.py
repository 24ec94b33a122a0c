"""The researcher's side: the study pages and their forms, the checklist of steps, the
monitor, the participant list, the preview, readiness to open, analysis reports, and
editing or removing what a study holds."""
