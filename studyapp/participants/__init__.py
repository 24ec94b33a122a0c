"""The participant's side: their path through a study (``path.PATH``), the views that
guard it, their enrolment and reserved pages, questionnaires, and simulated participants
that walk the path over HTTP."""
