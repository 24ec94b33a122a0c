"""The researcher's side: the study pages (``views``, ``urls``), the pages outside any
one study (``site_views``), a study's definition as a file (``definition_views``) and
its bundle's download and import (``bundle_views``), with what they call in three rooms:
``setup`` (building a study: its forms, checklist, readiness, preview, editing, removal
and copies), ``results`` (the monitor, the reports and the exports) and ``crowd`` (the
participant list and the crowd platform's page)."""
