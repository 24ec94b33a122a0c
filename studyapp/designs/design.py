"""What a rating design is: everything that differs between designs, as one class.

A design says how a participant's pages are planned (which clips, in which slots, which
are attention checks), what its rating page shows, how its form is read and checked,
what an instructed check asks on it, which answers exclude a participant, what columns
it adds to the ratings table, and which tables the monitor and the report show. The rest
of the app asks the study's design (``registry.design_of(study)``) and never compares a
design's name. What every design shares is done once around these methods: enrolment
(``participants.assignment``), storing an answer with the full-play rule
(``designs.answers``), the page views (``designs.pages``) and the export
(``researchers.results.export``).

Page contexts are plain data (strings, numbers, lists and dicts), so that a view can
send them as JSON as well as render them.
"""

from __future__ import annotations

import math
import random
from collections import Counter
from dataclasses import dataclass, field
from datetime import datetime
from typing import TYPE_CHECKING

import pandas as pd
from django.db.models import QuerySet
from django.http import QueryDict

from analysis.ratings.exclusions import ExclusionRules
from studyapp.models import Assignment, Rating, Stimulus, Study, System

if TYPE_CHECKING:
    from analysis.reports.design_report import DesignReport
    from analysis.reports.single_report import Report

PageKey = frozenset[int]  # the ids of a page's clips other than BAD: what a page's load counts
TIME_FIELDS = ("started_s", "ended_s", "answered_s", "played_until_s")  # a clip's times on the page's form


@dataclass
class PlannedPage:
    """One page of a participant's plan: its clips in slot order."""

    clips: list[Stimulus]
    is_check: bool = False  # an attention check: BAD (or NAT) placed to test the participant
    expected: list[str] = field(default_factory=list)  # an instructed check's answer, per clip

    @property
    def key(self) -> PageKey:
        return frozenset(s.id for s in self.clips if s.system.role != System.Role.BAD)


@dataclass(frozen=True)
class ClientTimes:
    """What the participant's browser reports of one clip, in seconds after its page was shown."""

    started_s: float | None = None  # the video began playing
    ended_s: float | None = None  # the video reached its end
    answered_s: float | None = None  # the answer was clicked or keyed
    played_until_s: float | None = None  # the video's position at the answer


@dataclass(frozen=True)
class Answer:
    """What a page's form sent, read by its design: per slot the times and any rating value,
    and a preference that stands for the whole page (``Rating.answer``)."""

    page: str  # the token of the page's first clip, which its form names it by
    times: dict[int, ClientTimes]
    values: dict[int, int] = field(default_factory=dict)
    choice: str = ""
    strength: int | None = None
    moved: frozenset[int] = frozenset()  # the slots whose slider the participant moved (side-by-side)
    reasons: tuple[str, ...] = ()  # the reasons ticked for the answer, in the study's words (``designs.reasons``)
    other_reason: str = ""  # the participant's own words under "Other"


@dataclass(frozen=True)
class PageClip:
    """A clip as a page shows it (nothing here names its system)."""

    slot: int
    token: str  # its assignment's token ("" on practice and preview pages)
    video_url: str
    seconds: float
    control_id: int | None = None
    expected: str = ""  # an instructed check's answer for this clip
    shown_control_id: int | None = None  # a mismatched clip's page's control (``Stimulus.shown_control``)


@dataclass(frozen=True)
class Page:
    """A page to show: its clips, where its form goes and the participant's progress."""

    clips: list[PageClip]
    action: str  # the URL name its form posts to
    form: dict[str, str]  # hidden fields naming what is answered
    heading: str
    done: int
    total: int
    upcoming: list[str] = field(default_factory=list)  # the next page's video URLs, fetched meanwhile


@dataclass(frozen=True)
class OnPage:
    """A clip being answered, as storing the answer needs it."""

    assignment: Assignment
    system: str  # its name in the ratings table (NAT and BAD for their roles)
    seconds: float


def rated_clip_exclusion(rules: ExclusionRules, study: Study, page: list[OnPage], answer: Answer) -> str:
    """Why the values given to a page's clips exclude the participant ("" if they do not):
    the attention rules on the study's scale, clip by clip."""
    scale = (study.scale_min, study.scale_max)
    for clip in page:
        value = answer.values[clip.assignment.slot]
        if rules.rated_attention_high(clip.system, value, *scale):
            return rules.attention_reason
        if rules.rated_natural_low(clip.system, value, *scale):
            return rules.natural_reason
    return ""


def clip_label(slot: int) -> str:
    """The neutral name of the clip at ``slot`` (1: A; past Z, or a slot a form made up, its number)."""
    return chr(ord("A") + slot - 1) if 1 <= slot <= 26 else str(slot)


class Design:
    """One rating design. Subclasses set the class attributes and implement what they
    lack; ``registry.DESIGNS`` names each with its class."""

    template: str  # the rating page, under templates/studyapp/participant/
    page_word = "Page"  # the heading's "Page 3 of 8"
    count_field = "pages_per_participant"  # the study's field saying how many pages a participant answers
    form_field = "page"  # the hidden field naming the page on its form
    default_scale: tuple[int, int] | None = None  # a new study's scale, where the design has its own
    # The study's fields that this design reads beyond the common ones (a design's
    # settings as plain data: the form shows them, a study file would hold them).
    settings: tuple[str, ...] = ()
    export_columns: tuple[str, ...] = ()  # its columns in front of the ratings table's (docs/ratings-schema.md)
    on_scale = True  # answers are values on the study's scale (pairwise: a preference instead)
    # Its pages show clips made for another control than the page's (appropriateness):
    # those are planned and rendered with the others (``stimuli.mismatched``), and every
    # clip is drawn over the path of the control its page shows.
    mismatched_clips = False
    power_table = True  # the monitor shows the ratings needed for 80 % power per pair of systems
    # The system whose clips its BAD checks are made of: a BAD system's clips, or NAT's
    # clips set against a path they obviously do not follow (appropriateness).
    attention_check_role = System.Role.BAD

    def __init__(self, name: str) -> None:
        self.name = name

    def __repr__(self) -> str:
        return f"<{type(self).__name__} design {self.name!r}>"

    # The study's settings.

    def page_count(self, study: Study) -> int:
        """The pages a participant answers, attention and instructed checks included."""
        return getattr(study, self.count_field)

    def check_pages(self, study: Study) -> int:
        """A participant's pages that are attention checks of their own (not rated pages with an anchor)."""
        return 0

    def clips_per_page(self, study: Study) -> float:
        """How many clips a page shows, on average (for the study's expected duration)."""
        return 1.0

    def answers_per_page(self, study: Study) -> float:
        """How many answers a page takes, on average (a rating, a slider, a choice)."""
        return 1.0

    def practice_page_count(self, study: Study) -> int:
        """The practice pages a participant meets: ``training_clips`` clips in whole pages."""
        return math.ceil(study.training_clips / self.clips_per_page(study))

    def problems(self, study: Study) -> dict[str, str]:
        """What makes ``study``'s settings unworkable for this design, by field."""
        pages, checks = self.page_count(study), self.check_pages(study) + study.instructed_checks
        if pages == 0:
            return {self.count_field: f"a participant needs at least one {self.page_word.lower()}"}
        if checks >= pages:
            return {self.count_field: f"leave room for rated {self.page_word.lower()}s besides the {checks} "
                                      f"attention and instructed check(s)"}
        return {}

    # Planning a participant's pages (the study's lock is held: loads cannot move).

    def loads(self, study: Study, cutoff: datetime) -> Counter:
        """Load of each page content (``PageKey``): answers that will be kept plus pages held
        by participants active since ``cutoff``, whatever the clips' status now (enrolment
        reads the rendered clips before it takes the lock). Pages are handed out least
        loaded first and never past ``ratings_per_stimulus``."""
        raise NotImplementedError

    def plan(self, study: Study, rendered: list[Stimulus], loads: Counter, count: int,
             rng: random.Random) -> list[PlannedPage]:
        """Up to ``count`` pages in presentation order, attention checks included (empty
        when every page has reached its target). ``rendered``: the study's finished
        clips, each with its system."""
        raise NotImplementedError

    def makes_attention_checks(self, study: Study, finished: QuerySet[Stimulus]) -> bool:
        """Whether the study's ``finished`` clips give ``plan`` any attention-check page."""
        return finished.filter(system__role=self.attention_check_role).exists()

    def practice(self, study: Study, rendered: list[Stimulus], planned: list[PlannedPage],
                 rng: random.Random) -> list[int]:
        """The practice clips (``training_clips`` of them, in whole pages of this design),
        as ids in the order they are shown, none on the participant's rated pages."""
        raise NotImplementedError

    def practice_pages(self, clips: list[Stimulus]) -> list[list[Stimulus]]:
        """The participant's practice clips grouped into the pages that show them."""
        return [[clip] for clip in clips]

    # Instructed checks: a rated page repeated with the answer it must be given.

    def instructed_answer(self, study: Study, clips: list[Stimulus], rng: random.Random) -> list[str]:
        """The answer an instructed check of these clips asks for, per clip."""
        raise NotImplementedError

    def instruction(self, study: Study, expected: list[str]) -> str:
        """What the instructed check's page tells the participant to do."""
        raise NotImplementedError

    def follows_instruction(self, study: Study, expected: list[str], answer: Answer) -> bool:
        raise NotImplementedError

    # The page.

    def page_context(self, study: Study, page: Page) -> dict:
        """The rating page's template context (plain data); subclasses add their own."""
        expected = [clip.expected for clip in page.clips]
        return {
            "clips": [{"slot": clip.slot, "label": clip_label(clip.slot), "video_url": clip.video_url,
                       "seconds": clip.seconds} for clip in page.clips],
            "action": page.action, "form": page.form, "heading": page.heading, "done": page.done,
            "total": page.total, "percent": round(100 * page.done / page.total) if page.total else 100,
            "upcoming": page.upcoming, "time_fields": TIME_FIELDS,
            "instruction": self.instruction(study, expected) if any(expected) else "",
        }

    def task(self, study: Study) -> str:
        """What the instructions page says each page asks of the participant."""
        return (f"For each clip you will answer: {study.question} On a scale from {study.scale_min} "
                f"({study.label_min}) to {study.scale_max} ({study.label_max}).")

    # Answers.

    def read_answer(self, study: Study, form: QueryDict) -> Answer:
        """The answer a page's form sent (AnswerRefused, 400, for one that cannot be read)."""
        raise NotImplementedError

    def check_answer(self, study: Study, answer: Answer, slots: list[int]) -> None:
        """Refuse (AnswerRefused) an answer that does not fit the page of ``slots``."""
        raise NotImplementedError

    def exclusion_reason(self, rules: ExclusionRules, study: Study, page: list[OnPage], answer: Answer) -> str:
        """Why this answer to an attention check excludes the participant ("" if it does not)."""
        raise NotImplementedError

    # The ratings table, the monitor and the report.

    def export_fields(self, assignment: Assignment, rating: Rating) -> dict:
        """The row's values of ``export_columns`` (and of any shared column the design
        words otherwise: an appropriateness check page names its system BAD)."""
        return {}

    def monitor_tables(self, compared: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
        """What the analysis says so far of the compared systems' kept ratings."""
        return []

    def report_tables(self, report: Report | DesignReport) -> list[tuple[str, pd.DataFrame]]:
        """The report's tables as the report page shows them, in order."""
        raise NotImplementedError
