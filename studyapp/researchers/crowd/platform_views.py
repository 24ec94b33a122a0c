"""The platform page: the participant list's suggestions sent through the crowd
platform's API, each first as a dry run listing exactly what will be sent.

Behind login and owner checks like every researcher page, for Prolific and MTurk studies
only. The researcher's credentials are kept encrypted in their session
(``platforms.credentials``) and kept out of error reports. Applying rebuilds the plan
and sends only the calls the dry run showed, unchanged (``platforms.actions.chosen``).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import wraps

from django.contrib import messages
from django.http import Http404, HttpRequest, HttpResponse, QueryDict
from django.shortcuts import redirect, render
from django.views.decorators.cache import never_cache
from django.views.decorators.debug import sensitive_post_parameters
from django.views.decorators.http import require_POST

from studyapp.models import Study
from studyapp.platforms import credentials
from studyapp.platforms.actions import (
    BonusListError,
    PlanChanged,
    PlatformAPI,
    apply,
    bonus_calls,
    chosen,
    decision_calls,
    planned,
    platform_api,
    read_back,
    without_submission,
)
from studyapp.platforms.calls import Call, PlatformError
from studyapp.researchers.access import researcher_study
from studyapp.researchers.crowd.platform_forms import BonusForm, MTurkCredentialsForm, ProlificCredentialsForm

CREDENTIAL_FORMS = {Study.Platform.PROLIFIC: ProlificCredentialsForm, Study.Platform.MTURK: MTurkCredentialsForm}
SECRET_FIELDS = ("token", "secret_access_key")
LOG_LENGTH = 200


def _on_platform(view: Callable[..., HttpResponse]) -> Callable[..., HttpResponse]:
    """``researcher_study`` for a study paid through a platform (404 for a study on a plain link)."""

    @researcher_study
    @wraps(view)
    def guarded(request: HttpRequest, study: Study, *args, **kwargs) -> HttpResponse:
        if study.platform not in CREDENTIAL_FORMS:
            raise Http404("a study on a plain link has no platform to send requests to")
        return view(request, study, *args, **kwargs)

    return guarded


def _with_credentials(view: Callable[..., HttpResponse]) -> Callable[..., HttpResponse]:
    """``view(request, study, api)`` with the platform's API under the researcher's kept
    credentials; without them, back to the platform page asking for them."""

    @_on_platform
    @wraps(view)
    def guarded(request: HttpRequest, study: Study, *args, **kwargs) -> HttpResponse:
        kept = credentials.read(request.session, study.platform)
        if not kept:
            messages.error(request, f"Enter your {study.get_platform_display()} credentials first (they are kept "
                                    f"for {credentials.CREDENTIALS_TTL_S // 3600} hours at most).")
            return redirect("study-platform", pk=study.pk)
        return view(request, study, platform_api(study, kept), *args, **kwargs)

    return guarded


def _page(request: HttpRequest, study: Study, form=None, bonus_form=None, status: int = 200) -> HttpResponse:
    kept = credentials.read(request.session, study.platform)
    context = {
        "study": study, "kept": kept, "form": form or CREDENTIAL_FORMS[study.platform](),
        "bonus_form": bonus_form or BonusForm(), "address": platform_api(study, kept).address if kept else "",
        "log": study.platform_actions.select_related("participant", "researcher").order_by("-sent_at", "-pk")[:LOG_LENGTH],
        "hours": credentials.CREDENTIALS_TTL_S // 3600,
    }
    return render(request, "studyapp/researcher/platform.html", context, status=status)


@never_cache
@sensitive_post_parameters(*SECRET_FIELDS)
@_on_platform
def study_platform(request: HttpRequest, study: Study) -> HttpResponse:
    """Keep or forget the researcher's credentials; the actions, and what was sent."""
    if request.method != "POST":
        return _page(request, study)
    if request.POST.get("action") == "forget":
        credentials.forget(request.session, study.platform)
        messages.success(request, "Your credentials are forgotten.")
        return redirect("study-platform", pk=study.pk)
    form = CREDENTIAL_FORMS[study.platform](request.POST)
    if not form.is_valid():
        return _page(request, study, form=form, status=400)
    credentials.keep(request.session, study.platform, form.secret())
    messages.success(request, f"Kept for {credentials.CREDENTIALS_TTL_S // 3600} hours in this login session, "
                              f"encrypted.")
    return redirect("study-platform", pk=study.pk)


def _calls(study: Study, api, data: QueryDict) -> list[Call]:
    if data.get("kind") == "bonuses":
        return bonus_calls(study, api, data.get("bonuses", ""), data.get("reason", ""))
    return decision_calls(study, api)


@never_cache
@_with_credentials
@require_POST
def study_platform_dry_run(request: HttpRequest, study: Study, api: PlatformAPI) -> HttpResponse:
    """The requests an action would send, exactly; nothing is sent."""
    try:
        calls = _calls(study, api, request.POST)
    except BonusListError as error:
        bonus_form = BonusForm(request.POST)
        bonus_form.is_valid()
        bonus_form.add_error("bonuses", str(error))
        return _page(request, study, bonus_form=bonus_form, status=400)
    context = {"study": study, "api": api, "plan": planned(study, calls), "kind": request.POST.get("kind", ""),
               "bonuses": request.POST.get("bonuses", ""), "reason": request.POST.get("reason", "")}
    context["to_send"] = sum(not item.done_before for item in context["plan"])
    context["unsendable"] = without_submission(study) if context["kind"] != "bonuses" else []
    return render(request, "studyapp/researcher/platform_plan.html", context)


@never_cache
@_with_credentials
@require_POST
def study_platform_apply(request: HttpRequest, study: Study, api: PlatformAPI) -> HttpResponse:
    """Send the requests of the dry run that were left ticked, each once."""
    try:
        calls = chosen(_calls(study, api, request.POST), request.POST.getlist("call"))
    except (PlanChanged, BonusListError) as error:
        messages.error(request, f"Nothing was sent: {error}.")
        return _page(request, study, status=409)
    if not calls:
        messages.error(request, "Nothing was sent: no request was ticked.")
        return redirect("study-platform", pk=study.pk)
    results = apply(study, api, calls, request.user)
    return render(request, "studyapp/researcher/platform_results.html", {"study": study, "api": api, "results": results})


@never_cache
@_with_credentials
@require_POST
def study_platform_read(request: HttpRequest, study: Study, api: PlatformAPI) -> HttpResponse:
    """The platform's status of each submission beside the participant list's."""
    try:
        rows = read_back(study, api, request.user)
    except PlatformError as error:
        messages.error(request, f"Nothing was read: {error}")
        return redirect("study-platform", pk=study.pk)
    return render(request, "studyapp/researcher/platform_read.html", {"study": study, "api": api, "rows": rows})


__all__ = ["study_platform", "study_platform_apply", "study_platform_dry_run", "study_platform_read"]
