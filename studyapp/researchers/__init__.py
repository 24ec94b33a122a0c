"""The researcher's side: the study pages (``views``, ``urls``), the pages outside any
one study (``site_views``) and a study's definition as a file (``definition_views``),
with what they call in three rooms: ``setup`` (building a study: its forms, checklist,
readiness, preview, editing, removal and copies), ``results`` (the monitor, the reports
and the exports) and ``crowd`` (the participant list and the crowd platform's page)."""
