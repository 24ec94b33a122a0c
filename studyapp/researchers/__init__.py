"""The researcher's side: the URL map (``urls``), who reaches a study (``access``), its
files as downloads (``downloads``), the pages outside any one study (``site_views``), a
study's definition as a file (``definition_views``) and its bundle (``bundle_views``);
each room holds its own pages beside what they call: ``setup`` (building a study),
``results`` (the monitor, the reports and the exports) and ``crowd`` (the participant
list and the crowd platform's page)."""
