"""The study's participants as the crowd platform pays them: the participant list's pages
(``participant_views``) with its suggested actions, the completion time that sets the pay,
and the platform page that sends the actions (``platform_views``)."""
