"""A board's fit on the votes of all its rounds.

Each round's study's ratings table is read as its report reads it (`studyapp.researchers.
results.monitor.flagged_ratings`: the study's exclusion rules applied, attention-check pages
left out by `analysis.ratings.exclusions.compared_ratings`), and never written. The rounds in the fit
are concatenated into one vote table with a ``round`` column (the round's number on the
board), each participant named by round and code (a participant of two rounds is two
participants of the bootstrap), and every page in one cell: the board pools the rounds'
tasks and control classes. `analysis.reports.leaderboard_report.build_leaderboard` fits it: the
weighted Bradley-Terry model on the Elo scale, the board's anchor (NAT by default) at 1000
where it was compared, else the systems' mean, and bootstrap intervals over participants.

Systems across rounds are one system when their names in the ratings table are equal
(``System.export_name``: the system's name; NAT and BAD for the natural and attention roles).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import date

import pandas as pd

from analysis.errors import AnalysisInputError
from analysis.ratings.exclusions import compared_ratings
from analysis.rankings.leaderboard import RESAMPLES
from analysis.reports.leaderboard_report import LeaderboardReport, build_leaderboard
from studyapp.designs.rules import StudyRules
from studyapp.leaderboards.models import Leaderboard, Round
from studyapp.researchers.results.monitor import flagged_ratings

ROUND = "round"
BOARD_TASK, BOARD_CLASS = "board", "all rounds"  # the one cell every round's pages are pooled into
SAME_SYSTEM_RULE = ("Systems of different rounds are the same system when their names in the ratings table are "
                    "equal (the natural motion is NAT in every round).")


@dataclass(frozen=True)
class RoundSummary:
    """One round as the board lists it: its number, name, dates, votes and systems."""

    number: int
    round: Round
    name: str
    in_fit: bool
    left_out_because: str
    pages: int  # compared pages (votes)
    participants: int  # kept participants
    first_vote: date | None
    last_vote: date | None
    systems: list[str]
    new_systems: list[str]  # first seen on the board (among the rounds in the fit) in this round


@dataclass
class BoardFit:
    """A board's fit (``report`` is None when no round has votes that can be fitted), the
    per-system table (``systems``), its rounds and the notes on what was left out and why."""

    board: Leaderboard
    rounds: list[RoundSummary]
    votes: pd.DataFrame
    report: LeaderboardReport | None
    systems: pd.DataFrame
    notes: list[str] = field(default_factory=list)

    @property
    def rounds_in_fit(self) -> list[RoundSummary]:
        return [r for r in self.rounds if r.in_fit]


def round_name(round_: Round) -> str:
    """A round's name on the board: its study's title."""
    return round_.study.title


def round_votes(round_: Round, number: int) -> pd.DataFrame:
    """The compared rows of a round's study, with its ``round`` number, participants named by
    round, and the board's one cell (empty, with the columns, when nothing was answered)."""
    flagged = flagged_ratings(round_.study)
    compared = compared_ratings(flagged, StudyRules.of(round_.study).exclusion) if len(flagged) else flagged
    return compared.assign(**{ROUND: number}, participant=[f"round {number} · {p}" for p in compared["participant"]],
                           task=BOARD_TASK, control_class=BOARD_CLASS)


def _vote_days(votes: pd.DataFrame) -> pd.Series:
    return pd.to_datetime(votes["answered_at"], utc=True, format="ISO8601").dt.date


def _summaries(rounds: list[Round], tables: list[pd.DataFrame]) -> list[RoundSummary]:
    seen: set[str] = set()
    out = []
    for number, (round_, table) in enumerate(zip(rounds, tables), start=1):
        systems = sorted(set(table["system"]))
        new = [s for s in systems if s not in seen] if round_.in_fit else []
        if round_.in_fit:
            seen |= set(systems)
        days = _vote_days(table) if len(table) else pd.Series([], dtype=object)
        out.append(RoundSummary(number, round_, round_name(round_), round_.in_fit, round_.left_out_because,
                                table.groupby(["participant", "page"]).ngroups if len(table) else 0,
                                table["participant"].nunique(), days.min() if len(days) else None,
                                days.max() if len(days) else None, systems, new))
    return out


def _since(votes: pd.DataFrame, summaries: list[RoundSummary]) -> pd.DataFrame:
    """Per system: the first round in the fit it was compared in, that round's name, the day
    of its first vote, and how many rounds in the fit compared it."""
    names = {s.number: s.name for s in summaries}
    days = votes.assign(day=_vote_days(votes))
    per = days.groupby("system").agg(first_round=(ROUND, "min"), since=("day", "min"), rounds=(ROUND, "nunique"))
    per["first_round_name"] = per["first_round"].map(names)
    return per.reset_index()


def fit_board(board: Leaderboard, resamples: int = RESAMPLES, seed: int = 0) -> BoardFit:
    """The board's fit on the votes of its rounds in the fit (see the module's docstring)."""
    rounds = list(board.rounds.select_related("study").order_by("added", "pk"))
    tables = [round_votes(r, n) for n, r in enumerate(rounds, start=1)]
    summaries = _summaries(rounds, tables)
    notes = [f"Round {s.number} ({s.name}) is left out of the fit"
             + (f": {s.left_out_because}." if s.left_out_because else ".") for s in summaries if not s.in_fit]
    used = [t for r, t in zip(rounds, tables) if r.in_fit and len(t)]
    votes = pd.concat(used, ignore_index=True) if used else pd.DataFrame(columns=[ROUND, "system", "participant"])
    if votes["system"].nunique() < 2:
        notes.append("No fit yet: the rounds in the fit have votes on fewer than two systems.")
        return BoardFit(board, summaries, votes, None, pd.DataFrame(), notes)
    try:
        report = build_leaderboard(votes, None, resamples=resamples, seed=seed, natural=board.anchor)
    except AnalysisInputError as error:
        notes.append(f"No fit: {error}.")
        return BoardFit(board, summaries, votes, None, pd.DataFrame(), notes)
    notes += report.notes
    systems = report.board.merge(_since(votes, summaries), on="system", how="left")
    return BoardFit(board, summaries, votes, report, systems, notes)
