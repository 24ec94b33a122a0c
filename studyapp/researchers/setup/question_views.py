"""The questions before and after the ratings: added, removed, changed and moved, until anyone has started."""

from __future__ import annotations

from django.contrib import messages
from django.http import HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.views.decorators.http import require_POST

from studyapp.models import Question, Study
from studyapp.preregistration.fixed import started
from studyapp.researchers.access import researcher_study
from studyapp.researchers.setup import question_order
from studyapp.researchers.setup.forms import QuestionForm, QuestionRemovalForm


@researcher_study
def study_questions(request: HttpRequest, study: Study) -> HttpResponse:
    """Questions before the ratings (screening) and after them; fixed once anyone has started."""
    locked = started(study)
    form = QuestionForm(instance=Question(study=study))
    status = 200
    if request.method == "POST":
        if locked:
            messages.error(request, "Participants have started: the questions are fixed.")
            return redirect("study-questions", pk=study.pk)
        if request.POST.get("action") == "remove":
            removal = QuestionRemovalForm(request.POST, study=study)
            if removal.is_valid():
                question = removal.cleaned_data["question"]
                question.delete()
                messages.success(request, f"Removed “{question.text}”.")
                return redirect("study-questions", pk=study.pk)
            messages.error(request, "Nothing removed: " + " ".join(removal.errors["question"]))
        else:
            form = QuestionForm(request.POST, instance=Question(study=study))
            if form.is_valid():
                form.instance.order = question_order.last_place(form.instance)
                messages.success(request, f"Added “{form.save().text}”.")
                return redirect("study-questions", pk=study.pk)
        status = 400
    # In the order participants meet them: the questions before the ratings first.
    questions = study.questions.order_by("-part", "order", "created", "pk")
    context = {"study": study, "form": form, "locked": locked, "questions": questions}
    return render(request, "studyapp/researcher/questions.html", context, status=status)


@researcher_study
def study_question_edit(request: HttpRequest, study: Study, question: int) -> HttpResponse:
    """Change a question (its text, choices, part, ...) until anyone has started."""
    target = get_object_or_404(Question, pk=question, study=study)
    locked = started(study)
    part = target.part
    form = QuestionForm(request.POST or None, instance=target)
    status = 200
    if request.method == "POST":
        if locked:
            messages.error(request, "Participants have started: the questions are fixed.")
            return redirect("study-questions", pk=study.pk)
        if form.is_valid():
            if form.instance.part != part:  # it joins the other part at its end
                form.instance.order = question_order.last_place(form.instance)
            messages.success(request, f"Saved “{form.save().text}”.")
            return redirect("study-questions", pk=study.pk)
        status = 400
    return render(request, "studyapp/researcher/question_edit.html",
                  {"study": study, "form": form, "question": target, "locked": locked}, status=status)


@researcher_study
@require_POST
def study_question_move(request: HttpRequest, study: Study, question: int) -> HttpResponse:
    """Move a question one place up or down (``direction`` "up" or "down") within its part."""
    target = get_object_or_404(Question, pk=question, study=study)
    step = {"up": -1, "down": 1}.get(request.POST.get("direction", ""))
    if step is None:
        return HttpResponse("direction must be up or down", status=400, content_type="text/plain")
    if started(study):
        messages.error(request, "Participants have started: the questions are fixed.")
    elif not question_order.move(target, step):
        messages.error(request, f"“{target.text}” is {'first' if step < 0 else 'last'} of its part already.")
    return redirect("study-questions", pk=study.pk)


__all__ = ["study_question_edit", "study_question_move", "study_questions"]
