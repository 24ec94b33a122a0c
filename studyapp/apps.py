"""Django app configuration for the study app."""

from django.apps import AppConfig


class StudyappConfig(AppConfig):
    name = "studyapp"
    verbose_name = "Motion rating study"

    def ready(self) -> None:
        from studyapp.preregistration import lock

        register_designs()
        lock.connect()  # opening a study locks its plan; later changes are recorded as deviations


def register_designs() -> None:
    """Enter the rating designs in the table the models read (studyapp.designs.registry),
    in the order the researcher sees them; each design's module imports the models."""
    from studyapp.designs import registry
    from studyapp.designs.appropriateness_pages import Appropriateness
    from studyapp.designs.pairwise_pages import Pairwise
    from studyapp.designs.side_by_side_pages import SideBySide
    from studyapp.designs.single_pages import SingleClip

    registry.register("single", "single clip per page, rated on the scale", SingleClip)
    registry.register("side-by-side", "side by side: every system's clip of one control on a page, each on a slider",
                      SideBySide)
    registry.register("pairwise", "pairwise: two systems' clips of one control, which is better", Pairwise)
    registry.register("appropriateness", "appropriateness: a system's clip for the shown control beside its clip for "
                                         "another control, which fits better", Appropriateness)
