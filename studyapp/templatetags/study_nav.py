"""``{% study_checklist study %}``: the researcher's checklist of a study, on each study page."""

from django import template

from studyapp.models import Study
from studyapp.researchers.setup.checklist import checklist

register = template.Library()


@register.inclusion_tag("studyapp/researcher/_checklist.html", takes_context=True)
def study_checklist(context: template.Context, study: Study) -> dict:
    return {"study": study, "items": checklist(study), "here": context["request"].path}
