"""The rating designs: single clips, side-by-side pages and pairwise pages, how their
pages are planned and answered, their instructed checks and the ratings table."""
