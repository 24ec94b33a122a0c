"""The rating designs: one object per design (``single_pages``, ``side_by_side_pages``,
``pairwise_pages``, ``appropriateness_pages``, each a ``design.Design``) owning everything
that differs between them, named in ``registry``; what every design shares around them:
storing an answer (``answers``), the pages' contexts (``pages``) and the study's rules
(``rules``). The rest of the app asks ``registry.design_of(study)``.
"""
