"""``{% study_steps study %}``: the researcher's steps through a study, on each study page."""

from django import template

from studyapp.models import Study
from studyapp.researchers.checklist import study_steps as steps_of

register = template.Library()


@register.inclusion_tag("studyapp/researcher/_study_steps.html", takes_context=True)
def study_steps(context: template.Context, study: Study) -> dict:
    return {"study": study, "steps": steps_of(study), "here": context["request"].path}
