"""The board pages: the researcher's (behind login and owner checks, every form with its
CSRF token) and the public one (no login, read-only, only while the board is public, at its
unguessable address). The public page's fit is kept for ``PUBLIC_FIT_SECONDS`` (per board and
state of its rounds), so that visitors cannot make the server refit the bootstrap at will."""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from functools import wraps

from django.contrib import messages
from django.core.cache import cache
from django.contrib.auth.decorators import login_required
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.urls import reverse
from django.views.decorators.http import require_http_methods, require_POST, require_safe

from studyapp.leaderboards.fit import BoardFit, fit_board
from studyapp.leaderboards.forms import LeaderboardForm, RoundFitForm, RoundForm, is_rated
from studyapp.leaderboards.models import Leaderboard, Round
from studyapp.leaderboards.public import board_context, board_csv

CSV = "text/csv; charset=utf-8"
PUBLIC_FIT_SECONDS = 60


def researcher_board(view: Callable[..., HttpResponse]) -> Callable[..., HttpResponse]:
    """``view(request, board, ...)`` as a view of ``(request, pk, ...)``: behind the login, for
    the owner's board only (404 for another's), as `studyapp.researchers.access.researcher_study`
    guards a study's pages."""

    @login_required
    @wraps(view)
    def guarded(request: HttpRequest, pk: int, *args, **kwargs) -> HttpResponse:
        return view(request, get_object_or_404(Leaderboard, pk=pk, owner=request.user), *args, **kwargs)

    return guarded


def _public_fit(key: str) -> tuple[BoardFit, dict]:
    """The fit of the public board at ``key`` and its page's context, kept a while (404 unless
    the board is public); new votes show within ``PUBLIC_FIT_SECONDS``."""
    board = Leaderboard.objects.filter(public_key=key, public=True).first()
    if board is None:
        raise Http404("no public leaderboard at this address")
    state = [board.public_key, board.title, board.description, board.anchor,
             *board.rounds.order_by("pk").values_list("pk", "study__key", "in_fit", "left_out_because")]
    name = f"leaderboard-fit:{board.pk}:{hashlib.sha256(repr(state).encode()).hexdigest()}"
    kept = cache.get(name)
    if kept is None:
        fit = fit_board(board)
        kept = (fit, board_context(fit))
        cache.set(name, kept, PUBLIC_FIT_SECONDS)
    return kept


@login_required
@require_http_methods(["GET", "POST"])
def leaderboard_list(request: HttpRequest) -> HttpResponse:
    """The researcher's boards, and a new one."""
    form = LeaderboardForm(request.POST or None)
    if request.method == "POST":
        if form.is_valid():
            form.instance.owner = request.user
            board = form.save()
            messages.success(request, f"Created {board.title}.")
            return redirect("leaderboard", pk=board.pk)
        status = 400
    else:
        status = 200
    boards = Leaderboard.objects.filter(owner=request.user).prefetch_related("rounds")
    return render(request, "studyapp/leaderboard/list.html", {"boards": boards, "form": form}, status=status)


def _page(request: HttpRequest, board: Leaderboard, status: int = 200, **forms) -> HttpResponse:
    fit = fit_board(board)
    rounds = {summary.round.pk: summary for summary in fit.rounds}
    context = {
        **board_context(fit),
        "settings_form": forms.get("settings_form") or LeaderboardForm(instance=board),
        "round_form": forms.get("round_form") or RoundForm(owner=request.user),
        "round_forms": [(rounds[r.pk], forms.get(f"fit_{r.pk}") or RoundFitForm(instance=r, prefix=f"round-{r.pk}"))
                        for r in board.rounds.order_by("added", "pk")],
        "removable": {r.pk for r in board.rounds.all() if not is_rated(r)},
        "public_url": request.build_absolute_uri(reverse("leaderboard-public", args=[board.public_key])),
    }
    return render(request, "studyapp/leaderboard/board.html", context, status=status)


@researcher_board
@require_safe
def leaderboard_page(request: HttpRequest, board: Leaderboard) -> HttpResponse:
    """The board: its fit, rounds and settings, and the preview of its public page."""
    return _page(request, board)


@researcher_board
@require_POST
def leaderboard_settings(request: HttpRequest, board: Leaderboard) -> HttpResponse:
    form = LeaderboardForm(request.POST, instance=board)
    if not form.is_valid():
        return _page(request, Leaderboard.objects.get(pk=board.pk), 400, settings_form=form)
    form.save()
    messages.success(request, "Saved the board's settings" + (": its public page is on." if board.public else "."))
    return redirect("leaderboard", pk=board.pk)


@researcher_board
@require_POST
def leaderboard_add_round(request: HttpRequest, board: Leaderboard) -> HttpResponse:
    form = RoundForm(request.POST, owner=request.user)
    if not form.is_valid():
        return _page(request, board, 400, round_form=form)
    round_ = Round.objects.create(leaderboard=board, study=form.cleaned_data["study"])
    messages.success(request, f"Added {round_.study.title} as round {board.rounds.count()}.")
    return redirect("leaderboard", pk=board.pk)


@researcher_board
@require_POST
def leaderboard_round_fit(request: HttpRequest, board: Leaderboard, round_pk: int) -> HttpResponse:
    round_ = get_object_or_404(Round, pk=round_pk, leaderboard=board)
    form = RoundFitForm(request.POST, instance=round_, prefix=f"round-{round_.pk}")
    if not form.is_valid():
        return _page(request, board, 400, **{f"fit_{round_.pk}": form})
    form.save()
    messages.success(request, f"{round_.study.title} is {'in' if round_.in_fit else 'left out of'} the fit.")
    return redirect("leaderboard", pk=board.pk)


@researcher_board
@require_POST
def leaderboard_remove_round(request: HttpRequest, board: Leaderboard, round_pk: int) -> HttpResponse:
    """Take a round added by mistake off the board while its study has no rating, so that the
    study can be added to another board (and its pairing no longer plans against this one's
    votes). A rated round stays: its votes may have been shown, so it can only leave the fit,
    with its reason on the board."""
    round_ = get_object_or_404(Round, pk=round_pk, leaderboard=board)
    if is_rated(round_):
        messages.error(request, f"{round_.study.title} has ratings, so it stays on the board: leave it out of the "
                                "fit instead, saying why.")
        return _page(request, board, 409)
    round_.delete()
    messages.success(request, f"Took {round_.study.title} off the board; it can be added to a board again.")
    return redirect("leaderboard", pk=board.pk)


def _csv(fit: BoardFit) -> HttpResponse:
    response = HttpResponse(board_csv(fit), content_type=CSV)
    response["Content-Disposition"] = f'attachment; filename="leaderboard-{fit.board.pk}.csv"'
    return response


@researcher_board
@require_safe
def leaderboard_csv(request: HttpRequest, board: Leaderboard) -> HttpResponse:
    """The board's table, the public page's CSV."""
    return _csv(fit_board(board))


@require_safe
def public_page(request: HttpRequest, key: str) -> HttpResponse:
    """The public board: read-only, no login (404 unless the researcher made it public)."""
    return render(request, "studyapp/leaderboard/public.html", _public_fit(key)[1])


@require_safe
def public_csv(request: HttpRequest, key: str) -> HttpResponse:
    return _csv(_public_fit(key)[0])
